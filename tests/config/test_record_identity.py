"""A measured calibration record holds the rig it was measured on (rig.toml's rig_id) and the
channel setup it was measured with (every channel's serial and gain): a sweep refuses it on
another rig or with a channel it calibrates changed (exit 2, naming the record file, the channel
and both values); an older record without them still loads, with one warning. `calibrate` adds
calibration_record among rig.toml's top-level keys when rig.toml has none (docs/calibration.md)."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from orbitrig import config as cfg
from orbitrig.errors import ConfigError

from support.paths import ROOT
from support.rig_configs import patient_lab
from support.store_checks import small_matrix
from support.cli_helpers import orbitrig, orbitrig_here

pytestmark = pytest.mark.timeout(240)

SPEEDUP = "20"  # as tests/e2e: the drives' watchdog holds with both cores busy
#: revolutions averaged per reading of a calibration step: what these tests check (the rig and the
#: channel setup a record holds, the records a sweep accepts or refuses) does not depend on how
#: well the step averaged (its default 50 or 100 took 3 s of the simulator per step, at SPEEDUP)
REVOLUTIONS = "10"


def calibrate(step: str, rig: Path) -> None:
    args = ("--config", str(rig), "--operator", "ada", "--speedup", SPEEDUP, "--revolutions", REVOLUTIONS)
    p = orbitrig("calibrate", step, "--sim", *args)
    assert p.returncode == 0, p.stdout + p.stderr


def sweep(rig: Path, out: Path, refused: bool = False) -> subprocess.CompletedProcess:
    """A one-point `orbitrig sweep --sim` with ``rig`` into ``out`` (``refused``: one expected to
    end before it starts anything, run in this process)."""
    matrix = out.parent / "matrix.toml"
    matrix.write_text(small_matrix("identity", 8, spin_rpm=(1000.0,)))
    args = ("sweep", "--sim", "--config", str(rig), "--matrix", str(matrix), "--out", str(out))
    args += ("--speedup", SPEEDUP, "--no-draw-figures", "--operator", "ada")
    return orbitrig_here(*args) if refused else orbitrig(*args, timeout=200)


@pytest.fixture(scope="module")
def lab(tmp_path_factory) -> Path:
    """A lab as `orbitrig init` writes it (rig_id SAC-DS-1), calibrated on the simulator by `loads`
    then `runout`: its active record calibrates the force channels and the probes."""
    folder = patient_lab(tmp_path_factory.mktemp("identity") / "lab")
    calibrate("loads", folder / "rig.toml")
    calibrate("runout", folder / "rig.toml")
    return folder / "rig.toml"


def lab_copy(lab: Path, tmp_path: Path, *changes: tuple[str, str]) -> Path:
    """A copy of the lab (its records included) with each (old, new) replaced once in rig.toml."""
    shutil.copytree(lab.parent, tmp_path / "lab2")
    rig = tmp_path / "lab2" / "rig.toml"
    text = rig.read_text()
    for old, new in changes:
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    rig.write_text(text)
    return rig


def active_path(rig: Path) -> Path:
    return rig.parent / "calibration" / f"{cfg.load_rig(rig).calibration_record}.toml"


def line_of(path: Path, start: str, after: str = "") -> int:
    """1-based number of the first line of ``path`` starting with ``start`` after the line ``after``."""
    lines = path.read_text().splitlines()
    begin = lines.index(after) if after else 0
    return next(n for n, ln in enumerate(lines[begin:], begin + 1) if ln.startswith(start))


STRAIN_X = ('gain = 0.1\noffset = 0.0\nserial = "SG-0417-X"', 'gain = 0.11\noffset = 0.0\nserial = "SG-9999-X"')


def test_a_record_holds_the_rigs_id_and_channel_setup_and_a_sweep_on_that_rig_uses_it(lab, tmp_path):
    path = active_path(lab)
    text = path.read_text()
    assert 'rig = "SAC-DS-1"' in text and 'step = "runout"' in text
    assert '[channels.fx_strain]\nserial = "SG-0417-X"\ngain = 0.1\n' in text
    assert '[channels.x_a]\nserial = "EC-5580-XA"\ngain = 5e-09\n' in text
    record = cfg.load_rig(lab).record
    assert record.loads and record.runout is not None  # the runout record carries the loads step's matrices
    shown = orbitrig_here("calibrate", "show", "--config", str(lab))
    assert shown.returncode == 0 and '[channels.y_b]\nserial = "EC-5583-YB"' in shown.stdout
    done = sweep(lab, tmp_path / "run")
    assert done.returncode == 0, done.stderr
    assert "cannot be checked" not in done.stderr and "Warning" not in done.stderr
    provenance = json.loads((tmp_path / "run" / "run.json").read_text())["provenance"]
    assert provenance["rig_id"] == "SAC-DS-1" and provenance["calibration_record"] == path.stem


def test_a_record_used_on_another_rig_is_refused_before_the_sweep_starts(lab, tmp_path):
    rig = lab_copy(lab, tmp_path, ('rig_id = "SAC-DS-1"', 'rig_id = "SAC-DS-2"'))  # `orbitrig init`'s name kept
    path = rig.parent / "calibration" / active_path(lab).name
    done = sweep(rig, tmp_path / "run", refused=True)
    assert done.returncode == 2, done.stdout + done.stderr
    assert not (tmp_path / "run").exists()  # nothing started
    line = line_of(path, "rig = ")
    assert f"{path}: line {line}: key 'rig': this runout record was measured on rig 'SAC-DS-1', not on the rig " in (
        done.stderr
    )
    assert f"{rig} (name 'double-spool rig', rig_id 'SAC-DS-2')" in done.stderr
    assert "Traceback" not in done.stderr


def test_a_record_used_with_a_changed_channel_is_refused_naming_channel_and_values(lab, tmp_path):
    y_a = ('name = "y_a"\nquantity = "displacement y, probe plane A"\nunit = "m"\ngain = 5e-9', "gain = 5e-9")
    rig = lab_copy(lab, tmp_path, STRAIN_X, (y_a[0], y_a[0].replace(*y_a[1:], "gain = 6e-9")))
    path = rig.parent / "calibration" / active_path(lab).name
    done = sweep(rig, tmp_path / "run", refused=True)
    assert done.returncode == 2, done.stdout + done.stderr
    assert not (tmp_path / "run").exists()  # nothing started
    at, rig_at = line_of(path, "serial", "[channels.fx_strain]"), line_of(rig, 'serial = "SG-9999-X"')
    assert (
        f"{path}: line {at}: key 'channels.fx_strain': this runout record calibrates fx_strain (loads) as "
        f"measured with serial 'SG-0417-X' and gain 0.1; {rig} (line {rig_at}) sets serial 'SG-9999-X' and gain 0.11"
    ) in done.stderr
    at, rig_at = line_of(path, "gain", "[channels.y_a]"), line_of(rig, "gain = 6e-9")
    assert (
        f"{path}: line {at}: key 'channels.y_a': this runout record calibrates y_a (runout) as measured with "
        f"gain 5e-09; {rig} (line {rig_at}) sets gain 6e-09. "
    ) in done.stderr
    assert "calibrate again (`orbitrig calibrate loads` `orbitrig calibrate runout`)" in done.stderr
    assert "channels.x_a" not in done.stderr and "channels.fy_strain" not in done.stderr  # unchanged
    # a calibration step is refused with it as well: nothing measured, nothing written
    names = cfg.list_names(rig.parent / "calibration")
    p = orbitrig_here("calibrate", "runout", "--sim", "--config", str(rig), "--speedup", SPEEDUP)
    assert p.returncode == 2 and "key 'channels.fx_strain'" in p.stderr, p.stderr
    assert cfg.list_names(rig.parent / "calibration") == names


def test_an_offset_or_a_channel_the_record_does_not_calibrate_may_change(lab, tmp_path):
    """An offset is not compared (re-zeroing is routine; the phasors have none); a channel no step of
    the record measured is not either (a `runout` record alone does not calibrate the force channels)."""
    rig = lab_copy(lab, tmp_path, ('offset = 0.0\nserial = "SG-0417-X"', 'offset = 12.5\nserial = "SG-0417-X"'))
    p = orbitrig_here("sweep", "--sim", "--dry-run", "--config", str(rig))
    assert p.returncode == 0, p.stderr
    assert cfg.load_rig(rig).channels[2].offset == 12.5
    data = cfg.load_rig(rig).record.model_dump()
    data.update(date="2026-12-03T08:00:00+00:00", loads={}, step="runout")
    name, _ = cfg.write_record(rig.parent / "calibration", cfg.CalibrationRecord.model_validate(data))
    cfg.activate(rig, name)
    text = rig.read_text()
    rig.write_text(text.replace(*STRAIN_X))
    assert cfg.load_rig(rig).calibration_record == name  # no loads: fx_strain is not its channel
    rig.write_text(text.replace('serial = "EC-5582-XB"', 'serial = "EC-0000-XB"'))
    with pytest.raises(ConfigError, match=r"key 'channels.x_b'.*serial 'EC-5582-XB'.*sets serial 'EC-0000-XB'"):
        cfg.load_rig(rig)


def _older_record(source: Path, rig: Path, rig_name: str, second: int) -> str:
    """The active record of ``source`` as orbitrig wrote records before they held the rig's id and
    channels (``rig``: rig.toml's name), written beside ``rig`` and made its active one: its name."""
    data = cfg.load_rig(source).record.model_dump(exclude={"channels"})
    data.update(date=f"2026-12-03T09:00:{second:02d}+00:00", rig=rig_name)
    name, text = cfg.write_record(rig.parent / "calibration", cfg.CalibrationRecord.model_validate(data))
    assert "channels" not in text
    cfg.activate(rig, name)
    return name


def test_an_older_record_still_loads_with_one_warning_that_it_cannot_be_checked(lab, tmp_path):
    """Another rig_id and another strain gauge: an older record cannot tell, so it loads, with a warning."""
    rig = lab_copy(lab, tmp_path, ('rig_id = "SAC-DS-1"', 'rig_id = "SAC-DS-2"'), STRAIN_X)
    name = _older_record(lab, rig, "double-spool rig", 0)
    path = rig.parent / "calibration" / f"{name}.toml"
    with pytest.warns(UserWarning, match="cannot be checked") as caught:
        loaded = cfg.load_rig(rig)
    assert loaded.calibration_record == name and loaded.record.runout is not None
    (w,) = [w for w in caught if "cannot be checked" in str(w.message)]
    assert w.filename == str(path) and w.lineno == line_of(path, "rig = ")
    assert str(rig) in str(w.message) and "this runout record" in str(w.message)
    p = orbitrig_here("sweep", "--sim", "--dry-run", "--config", str(rig))
    assert p.returncode == 0, p.stderr
    warned = [ln for ln in p.stderr.splitlines() if "cannot be checked" in ln]
    assert len(warned) == 1 and warned[0].startswith(f"{path}:{line_of(path, 'rig = ')}: UncheckedRecordWarning: ")
    # the rig's name of an older record is still checked: another name is another rig
    _older_record(lab, rig, "some other rig", 1)
    p = orbitrig_here("sweep", "--sim", "--dry-run", "--config", str(rig))
    assert p.returncode == 2 and "measured on rig 'some other rig'" in p.stderr, p.stderr


def _without_top_level(text: str, *keys: str) -> str:
    for key in keys:
        text, n = re.subn(rf"^{key} = .*\n", "", text, count=1, flags=re.MULTILINE)
        assert n == 1, key
    return text


@pytest.mark.parametrize(
    "removed, newline",
    [(("name", "calibration_record"), "\n"), (("name", "rig_id", "calibration_record"), "\n"), (("name",), "\r\n")],
    ids=["no-name", "no-top-level-key", "crlf-no-name"],
)
def test_activate_adds_calibration_record_among_the_top_level_keys(tmp_path, removed, newline):
    shutil.copytree(ROOT / "config" / "calibration", tmp_path / "calibration")
    text = _without_top_level((ROOT / "config" / "rig.toml").read_text(), *removed)
    if "calibration_record" not in removed:
        text = _without_top_level(text, "calibration_record")
    rig = tmp_path / "rig.toml"
    rig.write_bytes(text.replace("\n", newline).encode())
    name = cfg.load_rig(cfg.default_rig_path()).calibration_record
    cfg.activate(rig, name)
    after = rig.read_bytes().decode()
    loaded = cfg.load_rig(rig)  # the project's own loader: no key landed in a table
    assert loaded.calibration_record == name and [c.name for c in loaded.channels][0] == "fx_piezo"
    before_lines, after_lines = text.replace("\n", newline).splitlines(True), after.splitlines(True)
    added = [ln for ln in after_lines if ln.startswith("calibration_record")]
    assert added == [f'calibration_record = "{name}"{newline}']
    at = after_lines.index(added[0])
    assert at < next(i for i, ln in enumerate(after_lines) if ln.startswith("["))  # before the first table
    assert [ln for ln in after_lines if ln.strip()] == [
        ln for ln in before_lines[:at] + added + before_lines[at:] if ln.strip()
    ]  # every other line kept, in order (comments included)
    assert after.count("\r\n") == (after.count("\n") if newline == "\r\n" else 0)


def test_calibrate_on_a_rig_toml_without_name_writes_a_loadable_configuration(tmp_path):
    folder = patient_lab(tmp_path / "lab")
    rig = folder / "rig.toml"
    rig.write_text(_without_top_level(rig.read_text(), "name", "calibration_record"))
    calibrate("runout", rig)
    loaded = cfg.load_rig(rig)
    assert loaded.calibration_record.endswith("-runout") and loaded.name == "rig"
    p = orbitrig_here("calibrate", "list", "--config", str(rig))
    assert p.returncode == 0 and f"* {loaded.calibration_record}" in p.stdout, p.stderr
