"""`calibrate list` and `calibrate show` show the records' history whatever record is active, from
the folder the active record is read from (the shipped one for a rig.toml without its own): an
active record that sweep, serve and the steps refuse (measured on another rig, or with another
channel setup) is listed and shown, and said refused (a note on standard error naming the record
file and why), so that the history shows which record to make active instead. They refused it
(exit 2) like a sweep, listing nothing.

Real parts: the `orbitrig` command line (run in this process: none of these commands starts a
process or moves a drive) on a lab folder's files."""

from __future__ import annotations

import re
import shutil

from support.cli_helpers import orbitrig_here
from support.paths import ROOT

OTHER = "2026-12-01T000000Z-runout"


def _lab(tmp_path):
    """A lab whose active record was measured on another rig (its `rig`), typed in (no digest of its own)."""
    shutil.copy(ROOT / "config/rig.toml", tmp_path / "rig.toml")
    shutil.copytree(ROOT / "config/calibration", tmp_path / "calibration")
    initial = next((tmp_path / "calibration").glob("*-initial.toml"))
    text = initial.read_text().replace('step = "initial"', 'step = "runout"')
    text = re.sub(r"^sha256 = .*\n", "", text, count=1, flags=re.M)
    text = re.sub(r'^rig = ".*"$', 'rig = "OTHER-RIG"', text, count=1, flags=re.M)
    (tmp_path / "calibration" / f"{OTHER}.toml").write_text(text)
    rig = tmp_path / "rig.toml"
    rig.write_text(
        re.sub(r'^calibration_record = "[^"]*"', f'calibration_record = "{OTHER}"', rig.read_text(), flags=re.M)
    )
    return rig, initial.stem


def test_list_and_show_show_the_history_with_a_refused_record_active(tmp_path):
    rig, initial = _lab(tmp_path)
    refused = f"{tmp_path / 'calibration' / OTHER}.toml: line "
    listed = orbitrig_here("calibrate", "list", "--config", str(rig))
    assert listed.returncode == 0, listed.stderr
    assert re.search(rf"^\* {OTHER} .* runout ", listed.stdout, re.M), listed.stdout
    assert re.search(rf"^  {initial} ", listed.stdout, re.M), listed.stdout
    note = f"note: the active record is refused by sweep, serve and the steps: {refused}"
    assert note in listed.stderr and "measured on rig 'OTHER-RIG'" in listed.stderr, listed.stderr
    shown = orbitrig_here("calibrate", "show", "--config", str(rig))
    assert shown.returncode == 0 and f"{OTHER}.toml (active)" in shown.stdout, shown.stderr
    assert 'rig = "OTHER-RIG"' in shown.stdout and note in shown.stderr
    # what measures or corrects with it still refuses it
    dry = orbitrig_here("sweep", "--dry-run", "--sim", "--config", str(rig))
    assert dry.returncode == 2 and f"error: {refused}" in dry.stderr, dry.stderr


def test_list_and_show_read_the_folder_the_active_record_comes_from(tmp_path):
    """A rig.toml copied alone (no calibration/ beside it) takes its record from the shipped
    folder (docs/calibration.md): list and show read that one, where they said there was no record."""
    shutil.copy(ROOT / "config/rig.toml", tmp_path / "rig.toml")
    shipped = ROOT / "config" / "calibration"
    active = next(shipped.glob("*-initial.toml")).stem
    listed = orbitrig_here("calibrate", "list", "--config", str(tmp_path / "rig.toml"))
    assert listed.returncode == 0 and re.search(rf"^\* {active} ", listed.stdout, re.M), listed.stdout
    shown = orbitrig_here("calibrate", "show", "--config", str(tmp_path / "rig.toml"))
    assert shown.returncode == 0 and shown.stdout.startswith(f"# {shipped / active}.toml (active)\n"), shown.stderr
    assert not (tmp_path / "calibration").exists()
