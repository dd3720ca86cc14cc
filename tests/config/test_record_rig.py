"""The active calibration record must be this rig's: a record measured on another rig is refused
when the rig configuration is loaded (exit 2 before anything starts), naming the record file,
its rig and rig.toml's; the rig's own records, records naming no rig, the shipped initial record
under a renamed rig and a run's stored copy still load."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from orbitrig import config as cfg
from orbitrig.cli import app
from orbitrig.errors import ConfigError


@pytest.fixture
def rig_file(tmp_path) -> Path:
    """The lab's rig.toml (name 'double-spool rig', rig_id 'SAC-DS-1') with its records' folder."""
    src = cfg.default_rig_path()
    lab = tmp_path / "lab"
    shutil.copytree(src.parent / "calibration", lab / "calibration")
    shutil.copy(src, lab / "rig.toml")
    return lab / "rig.toml"


def measured(rig_file: Path, rig: str, second: int) -> tuple[str, str]:
    """A delay record of ``rig`` written beside ``rig_file`` and made the active one: (name, text)."""
    base = cfg.load_rig(rig_file).record.model_dump()
    base.update(
        date=f"2026-12-02T06:00:{second:02d}+00:00",
        operator="bob",
        rig=rig,
        step="delay",
        delay={"fx_piezo": {"phase_deg": 1.5, "delay_us": 20.0}},
    )
    name, text = cfg.write_record(rig_file.parent / "calibration", cfg.CalibrationRecord.model_validate(base))
    cfg.activate(rig_file, name)
    return name, text


def test_a_record_measured_on_another_rig_is_refused_naming_both_rigs(rig_file):
    initial = cfg.load_rig(rig_file).calibration_record
    ours, _ = measured(rig_file, "double-spool rig", 1)  # as `orbitrig calibrate` writes it: rig.toml's name
    assert cfg.load_rig(rig_file).record.delay["fx_piezo"].phase_deg == 1.5
    foreign, text = measured(rig_file, "some other rig", 2)
    with pytest.raises(ConfigError) as ei:
        cfg.load_rig(rig_file)
    err = ei.value
    path = rig_file.parent / "calibration" / f"{foreign}.toml"
    assert err.file == str(path)
    rig_line = text.splitlines().index('rig = "some other rig"') + 1
    key_line = next(
        n for n, ln in enumerate(rig_file.read_text().splitlines(), 1) if ln.startswith("calibration_record")
    )
    (p,) = err.problems
    assert p.startswith(
        f"line {rig_line}: key 'rig': this delay record was measured on rig 'some other rig', not on the rig of "
        f"{rig_file} (name 'double-spool rig', rig_id 'SAC-DS-1'), whose calibration_record (line {key_line}) "
        "makes it the active one"
    )
    assert f"Set calibration_record to a record of this rig (in {path.parent}: {initial}, {ours})" in p
    assert "or remove the key and calibrate this rig (`orbitrig calibrate" in p
    res = CliRunner().invoke(app, ["sweep", "--sim", "--dry-run", "--config", str(rig_file)])
    assert res.exit_code == 2 and f"{path}: line {rig_line}: key 'rig'" in res.stderr
    # a run made with it keeps its stored copy readable (resume and reports do not read the folder)
    stored = cfg.rig_from_text(rig_file.read_text(), "stored run", text)
    assert stored.record.rig == "some other rig"


def test_the_rigs_own_records_and_records_naming_no_rig_load(rig_file):
    for second, rig in enumerate(("SAC-DS-1", "", "double-spool rig")):  # rig_id, none, name
        name, _ = measured(rig_file, rig, second)
        assert cfg.load_rig(rig_file).calibration_record == name
    # the shipped initial record (`orbitrig init` writes a lab's from it) under a renamed rig
    text = rig_file.read_text().replace('name = "double-spool rig"', 'name = "lab rig"')
    rig_file.write_text(text)
    with pytest.raises(ConfigError, match=r"measured on rig 'double-spool rig', not on the rig of .*name 'lab rig'"):
        cfg.load_rig(rig_file)
    cfg.activate(rig_file, cfg.load_rig(cfg.default_rig_path()).calibration_record)
    assert cfg.load_rig(rig_file).record.step == "initial"
