"""How old the active calibration record's measurements are (orbitrig.config.record_age;
docs/calibration.md): each measured part dated by the record of its step among those the active
one started from; the dry run says the ages, and a part older than rig.toml's
calibration_valid_days is warned of (the plan's warnings: dry run, sweep start, run.log), the run
going on.

Real parts: the record files of a lab folder, and `orbitrig sweep --dry-run --sim` in this process."""

from __future__ import annotations

import datetime as _dt
import shutil
from pathlib import Path

import pytest

from orbitrig import config as cfg
from orbitrig.config.record_age import age_lines, age_warning, part_ages, validity
from orbitrig.errors import ConfigError

from support.cli_helpers import orbitrig_here
from support.paths import ROOT

NOW = _dt.datetime(2026, 12, 6, 12, 0, tzinfo=_dt.UTC)
RUNOUT = {"spin_rpm": 100.0, "revolutions": 4} | {
    p: {"h1_um": [0.1, 0.0], "h2_um": [0.0, 0.0]} for p in ("x_a", "y_a", "x_b", "y_b")
}


def _lab(tmp: Path, loads_date: _dt.datetime, runout_date: _dt.datetime, valid_days: str | None) -> Path:
    """A copy of the shipped lab: a loads record, then a runout record started from it (active);
    ``valid_days``: rig.toml's calibration_valid_days line (None: no such line)."""
    shutil.copy(ROOT / "config/rig.toml", tmp / "rig.toml")
    shutil.copytree(ROOT / "config/calibration", tmp / "calibration")
    rig = cfg.load_rig(tmp / "rig.toml")
    data = rig.record.model_dump() | cfg.identity(rig)
    data.update(date=loads_date.isoformat(), step="loads", previous=rig.calibration_record)
    data["loads"] = {"strain": {"gain": [[0.98, 0.001], [0.0, 0.99]], "gain_u": [[1e-4, 1e-4], [1e-4, 1e-4]]}}
    loads, _ = cfg.write_record(tmp / "calibration", cfg.CalibrationRecord.model_validate(data))
    data.update(date=runout_date.isoformat(), step="runout", previous=loads, runout=RUNOUT)
    runout, _ = cfg.write_record(tmp / "calibration", cfg.CalibrationRecord.model_validate(data))
    cfg.activate(tmp / "rig.toml", runout)
    if valid_days is not None:
        text = (tmp / "rig.toml").read_text()
        (tmp / "rig.toml").write_text(text.replace("\n[transports]", f"\n{valid_days}\n\n[transports]", 1))
    return tmp / "rig.toml"


def test_each_measured_part_is_dated_by_the_record_of_its_step_and_an_old_one_is_warned_of(tmp_path):
    rig_file = _lab(
        tmp_path, NOW - _dt.timedelta(days=400), NOW - _dt.timedelta(days=5), "calibration_valid_days = 365"
    )
    rig = cfg.load_rig(rig_file)
    parts = {p.step: p for p in part_ages(rig, NOW)}
    assert list(parts) == ["loads", "runout"]  # what the active record holds, in the steps' order
    assert parts["loads"].days == pytest.approx(400) and parts["loads"].record.endswith("-loads")
    assert parts["runout"].days == pytest.approx(5) and parts["runout"].record == rig.calibration_record
    assert all(p.traced for p in parts.values())
    line = next(n for n, t in enumerate(rig_file.read_text().splitlines(), 1) if t.startswith("calibration_valid"))
    warning = age_warning(rig, NOW)
    assert warning is not None and warning.startswith(
        f"line {line}: key 'calibration_valid_days': the active calibration record {rig.calibration_record} "
        f"holds loads 400 days old ({(NOW - _dt.timedelta(days=400)).date()}, record {parts['loads'].record}): "
        "older than calibration_valid_days = 365"
    ), warning
    assert "runout" not in warning.split("older than")[0].replace(rig.calibration_record, "")
    assert "`orbitrig calibrate loads`" in warning and "calibrate runout" not in warning
    (said,) = age_lines(rig, NOW)
    assert said.startswith(f"calibration: record {rig.calibration_record}: loads 400 days old (") and said.endswith(
        "runout 5 days old ({}, record {}); valid 365 days (calibration_valid_days)".format(
            (NOW - _dt.timedelta(days=5)).date(), rig.calibration_record
        )
    )
    assert age_warning(rig, NOW - _dt.timedelta(days=36)) is None  # 364 days old then: within
    # the loads record gone from the folder: its part is at least as old as the oldest record reached
    (tmp_path / "calibration" / f"{parts['loads'].record}.toml").unlink()
    (loads,) = [p for p in part_ages(cfg.load_rig(rig_file), NOW) if p.step == "loads"]
    assert not loads.traced and loads.days == pytest.approx(5) and loads.missing == parts["loads"].record
    assert (
        f"loads measured before {(NOW - _dt.timedelta(days=5)).date()}, at least 5 days old (its record not found: "
        f"the oldest record reached is {rig.calibration_record}; the records it started from break at "
        f"{parts['loads'].record}, not in the records' folder), runout 5 days old ("
    ) in age_lines(rig, NOW)[0]
    warning = age_warning(cfg.load_rig(rig_file), NOW)  # at least 5 days old: not shown within 365
    assert warning is not None and warning.endswith(
        f"{parts['loads'].record}, not in the records' folder): not shown to be within calibration_valid_days = 365; "
        "the run goes on, corrected by that calibration; calibrate again (`orbitrig calibrate loads`)"
    ), warning
    # there but unreadable (not TOML): the chain breaks at it, said with the file's own error
    (tmp_path / "calibration" / f"{parts['loads'].record}.toml").write_text("not = [toml\n")
    (loads,) = [p for p in part_ages(cfg.load_rig(rig_file), NOW) if p.step == "loads"]
    assert not loads.traced and loads.missing == parts["loads"].record
    assert loads.why.startswith(f"which does not read ({tmp_path / 'calibration' / parts['loads'].record}.toml")
    said = age_lines(rig, NOW)[0]
    assert (
        f"break at {parts['loads'].record}, which does not read (" in said and "not in the records' folder" not in said
    )


def test_no_limit_no_warning_a_bad_limit_refused_an_initial_record_has_nothing_measured(tmp_path):
    old = NOW - _dt.timedelta(days=4000)
    assert age_warning(cfg.load_rig(_lab(tmp_path, old, old, None)), NOW) is None
    (tmp_path / "zero").mkdir()
    with pytest.raises(ConfigError, match="calibration_valid_days"):
        cfg.load_rig(_lab(tmp_path / "zero", old, old, "calibration_valid_days = 0"))
    text = (ROOT / "config/rig.toml").read_text()
    limited = text.replace("\n[transports]", "\ncalibration_valid_days = 1\n\n[transports]", 1)
    shipped = cfg.rig_from_text(limited, str(ROOT / "config/rig.toml"))  # its initial record: typed in, 2026-11-26
    assert shipped.calibration_valid_days == 1 and part_ages(shipped, NOW) == [] and age_warning(shipped, NOW) is None
    assert age_lines(shipped, NOW) == [
        f"calibration: record {shipped.calibration_record} (initial): nothing measured yet; "
        "valid 1 days (calibration_valid_days)"
    ]


def test_the_dry_run_says_the_ages_and_warns_of_an_old_part(tmp_path):
    now = _dt.datetime.now(_dt.UTC)
    rig_file = _lab(tmp_path, now - _dt.timedelta(days=400), now - _dt.timedelta(days=2), "calibration_valid_days = 30")
    p = orbitrig_here("sweep", "--sim", "--dry-run", "--config", str(rig_file), "--out", str(tmp_path / "run"))
    assert p.returncode == 0, p.stderr
    (warned,) = [ln for ln in p.stderr.splitlines() if "calibration_valid_days" in ln]
    assert warned.startswith(f"warning: {rig_file}: line ") and "holds loads 400 days old" in warned, warned
    assert "older than calibration_valid_days = 30; the run goes on" in warned
    said = " ".join(p.stdout.split())  # the dry run's lines are wrapped
    assert "calibration: record " in said and "loads 400 days old" in said and "runout 2 days old" in said
    assert "valid 30 days (calibration_valid_days)" in said


def test_a_runs_provenance_says_whether_the_record_was_within_its_validity(tmp_path):
    """calibration_validity (run.json, run.h5, every export): expired, valid or no limit, then the
    parts' ages; an initial record has nothing measured; no record, nothing."""
    rig_file = _lab(
        tmp_path, NOW - _dt.timedelta(days=400), NOW - _dt.timedelta(days=5), "calibration_valid_days = 365"
    )
    rig = cfg.load_rig(rig_file)
    loads = next(p.record for p in part_ages(rig, NOW) if p.step == "loads")
    ages = (
        f"loads 400 days old ({(NOW - _dt.timedelta(days=400)).date()}, record {loads}), "
        f"runout 5 days old ({(NOW - _dt.timedelta(days=5)).date()}, record {rig.calibration_record})"
    )
    assert validity(rig, NOW) == f"expired: past calibration_valid_days = 365 at the run's start; {ages}"
    assert validity(rig, NOW - _dt.timedelta(days=36)).startswith(
        "valid: within calibration_valid_days = 365 at the run's start; loads 364 days old ("
    )
    bare = rig.text.replace("calibration_valid_days = 365\n", "")
    assert validity(cfg.rig_from_text(bare, str(rig_file)), NOW) == f"no limit: calibration_valid_days not set; {ages}"
    shipped = cfg.load_rig(ROOT / "config/rig.toml")
    assert validity(shipped, NOW) == "no limit: calibration_valid_days not set; nothing measured yet (initial record)"
    unnamed = "\n".join(t for t in shipped.text.splitlines() if not t.startswith("calibration_record"))
    assert validity(cfg.rig_from_text(unnamed, "rig.toml"), NOW) == ""
