"""A calibration record holds the SHA-256 of its own text (orbitrig.config.record_seal;
docs/calibration.md): a record edited after its step wrote it is refused where it is used (exit
2, naming the file and the line), listed and shown marked as edited; a measured record without
one (written before records held it) loads with a warning that it is not verifiable.

Real parts: the record files of a lab folder, and the `orbitrig` command line in this process."""

from __future__ import annotations

import hashlib
import re
import shutil
import warnings
from pathlib import Path

import pytest

from orbitrig import config as cfg
from orbitrig.config.record_seal import SealState, seal_state, text_digest
from orbitrig.errors import ConfigError

from support.cli_helpers import orbitrig_here
from support.paths import ROOT


def _lab(tmp: Path) -> tuple[Path, str, Path]:
    """A copy of the shipped rig.toml and records with a `loads` record of its own made active:
    (rig.toml, the record's name, its file)."""
    shutil.copy(ROOT / "config/rig.toml", tmp / "rig.toml")
    shutil.copytree(ROOT / "config/calibration", tmp / "calibration")
    rig = cfg.load_rig(tmp / "rig.toml")
    data = rig.record.model_dump() | cfg.identity(rig)
    data.update(date="2026-12-01T08:30:00+00:00", step="loads", previous=rig.calibration_record)
    data["loads"] = {"strain": {"gain": [[0.98, 0.001], [0.0, 0.99]], "gain_u": [[1e-4, 1e-4], [1e-4, 1e-4]]}}
    name, _ = cfg.write_record(tmp / "calibration", cfg.CalibrationRecord.model_validate(data))
    cfg.activate(tmp / "rig.toml", name)
    return tmp / "rig.toml", name, tmp / "calibration" / f"{name}.toml"


def _line(path: Path, start: str) -> int:
    return next(n for n, t in enumerate(path.read_text().splitlines(), 1) if t.startswith(start))


def test_a_written_record_holds_the_digest_of_its_text_without_that_line(tmp_path):
    rig_file, name, path = _lab(tmp_path)
    text = path.read_text()
    (held,) = re.findall(r'^sha256 = "([0-9a-f]{64})"', text, re.M)
    rest = re.sub(r"^sha256 = .*\n", "", text, flags=re.M)
    assert held == hashlib.sha256(rest.encode()).hexdigest() == text_digest(text)
    assert seal_state(text)[0] is SealState.VERIFIED
    rig = cfg.load_rig(rig_file)  # loads, no warning of any kind about it
    assert rig.calibration_record == name and rig.record.force_gain("strain")[0, 0] == 0.98
    assert seal_state(rig.record_text)[0] is SealState.VERIFIED  # the text a run stores can be verified
    shipped = next((ROOT / "config/calibration").glob("*-initial.toml")).read_text()
    assert seal_state(shipped)[0] is SealState.VERIFIED


def test_a_record_edited_after_it_was_written_is_refused_listed_and_shown_as_edited(tmp_path):
    rig_file, name, path = _lab(tmp_path)
    path.write_text(path.read_text().replace("gain = [[0.98, 0.001]", "gain = [[0.99, 0.001]"))  # a hand edit
    with pytest.raises(ConfigError, match="edited after it was written") as err:
        cfg.load_rig(rig_file)
    assert err.value.file == str(path) and f"line {_line(path, 'sha256 = ')}: key 'sha256'" in str(err.value)
    run = orbitrig_here("sweep", "--sim", "--dry-run", "--config", str(rig_file), "--out", str(tmp_path / "run"))
    assert run.returncode == 2 and f"{path}: line " in run.stderr, run.stderr
    assert "this loads record was edited after it was written" in run.stderr, run.stderr
    said = " ".join(run.stderr.split())  # how to make another record active, not only that one may
    assert "make another record active (its name as rig.toml's calibration_record; `orbitrig calibrate list`" in said
    listed = orbitrig_here("calibrate", "list", "--config", str(rig_file))
    assert listed.returncode == 0, listed.stderr
    assert re.search(rf"^\* {name} .*  EDITED AFTER IT WAS WRITTEN$", listed.stdout, re.M), listed.stdout
    assert re.search(r"^  \S+-initial .* reference -$", listed.stdout, re.M), listed.stdout  # as written
    assert "note: the active record is refused" in listed.stderr and "edited after it was written" in listed.stderr
    shown = orbitrig_here("calibrate", "show", "--config", str(rig_file))
    assert shown.returncode == 0 and "\n# EDITED after it was written: its sha256 line says " in shown.stdout
    # the digest's line itself changed: edited as well; put back as written: loads again
    written = path.read_text().replace("gain = [[0.99, 0.001]", "gain = [[0.98, 0.001]")
    path.write_text(re.sub(r'^sha256 = "[0-9a-f]{64}"', f'sha256 = "{"f" * 64}"', written, flags=re.M))
    with pytest.raises(ConfigError, match="edited after it was written"):
        cfg.load_rig(rig_file)
    path.write_text(written)
    assert cfg.load_rig(rig_file).calibration_record == name
    assert "an initial record is typed in" not in str(err.value)  # a measured one: calibrate again
    # the shipped initial record edited in place (a lab typing in its data sheets): told how to do it
    initial = next((tmp_path / "calibration").glob("*-initial.toml"))
    initial.write_text(initial.read_text().replace("probe_sensitivity_pct = 1.0", "probe_sensitivity_pct = 0.8"))
    cfg.activate(rig_file, initial.stem)
    with pytest.raises(ConfigError, match="an initial record is typed in: to type in your own values, save them "):
        cfg.load_rig(rig_file)
    assert "# as written" in orbitrig_here("calibrate", "show", name, "--config", str(rig_file)).stdout


def test_a_measured_record_without_a_digest_loads_with_a_warning_that_it_is_not_verifiable(tmp_path):
    rig_file, name, path = _lab(tmp_path)
    path.write_text(re.sub(r"^sha256 = .*\n", "", path.read_text(), flags=re.M))  # as written before digests
    with pytest.warns(cfg.UnverifiableRecordWarning, match="not verifiable") as caught:
        rig = cfg.load_rig(rig_file)
    assert rig.calibration_record == name
    (w,) = [w for w in caught if w.category is cfg.UnverifiableRecordWarning]
    assert w.filename == str(path) and w.lineno == _line(path, "step = ")
    listed = orbitrig_here("calibrate", "list", "--config", str(rig_file))
    assert re.search(rf"^\* {name} .*  not verifiable$", listed.stdout, re.M), listed.stdout
    # an initial record without one is typed in, not written by a step: not warned of
    initial = next((tmp_path / "calibration").glob("*-initial.toml"))
    initial.write_text(re.sub(r"^sha256 = .*\n", "", initial.read_text(), flags=re.M))
    cfg.activate(rig_file, initial.stem)
    with warnings.catch_warnings():
        warnings.simplefilter("error", cfg.UnverifiableRecordWarning)
        assert cfg.load_rig(rig_file).calibration_record == initial.stem
