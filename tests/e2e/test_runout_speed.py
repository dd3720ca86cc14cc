"""A runout measured at a spin as fast as a point's, or faster, is no slow roll for that point:
its 1x and 2x hold the spindle's own synchronous response at that speed besides the runout, and
the sweep takes them out as runout. The record's ``[runout] spin_rpm`` was written and never
read; now the plan warns (dry run and sweep start, run.log) naming the matrix line, the spins
and the record, once per matrix. A record older than rig.toml's calibration_valid_days is warned
of the same way.

Real parts: `orbitrig calibrate runout --sim` writes the record in a lab folder (a subprocess on
the simulator); `orbitrig sweep --sim --dry-run` and `orbitrig sweep --sim` read it."""

from __future__ import annotations

import csv
import json
import shutil

import h5py
import pytest

from orbitrig.config import load_matrix, load_rig, warning_lines
from support.rig_configs import patient_rig_config
from support.cli_helpers import orbitrig
from support.paths import ROOT

pytestmark = pytest.mark.timeout(300)

MATRIX = """name = "slow"
[operating]
spin_rpm = [{spin}]
recess_pressure_mpa = [0.4826]
pressure_ratio = [0.4]
static_eccentricity = [0.0]
dynamic_eccentricity = [0.096]
[orbit]
ratios = [0.5, 0.7]
directions = ["forward"]
revolutions = [6, 6]
[[models]]
model = "kc8"
"""


def _lab(tmp_path, spin_rpm: str):
    patient_rig_config(tmp_path)  # a link that holds with both cores busy
    shutil.copytree(ROOT / "config/calibration", tmp_path / "calibration")
    rig = tmp_path / "rig.toml"
    args = ("calibrate", "runout", "--sim", "--sim-config", "clean", "--config", str(rig), "--revolutions", "4")
    p = orbitrig(*args, "--spin-rpm", spin_rpm)
    assert p.returncode == 0, p.stderr
    # each runout phasor with its standard uncertainty from the 4 revolutions' scatter (the clean
    # scenario's probe noise: a few nm), printed and recorded
    runout = load_rig(rig).record.runout
    for probe in ("x_a", "y_a", "x_b", "y_b"):
        track = dict(runout)[probe]
        assert 0 < track.h1_u_um < 0.02 and 0 < track.h2_u_um < 0.02, track
        assert f"{probe}: runout 1x " in p.stdout and f"(u {track.h1_u_um:.3f}, {track.h2_u_um:.3f} µm)" in p.stdout
    return rig


def test_spins_not_above_the_runouts_slow_roll_are_warned_of_at_the_dry_run_and_the_sweep(tmp_path):
    rig = _lab(tmp_path, "900")
    record = load_rig(rig).calibration_record
    matrix = tmp_path / "slow.toml"
    matrix.write_text(MATRIX.format(spin="600.0, 900.0, 1500.0"))
    q = orbitrig("sweep", "--sim", "--sim-config", "clean", "--dry-run", "--config", str(rig), "--matrix", str(matrix))
    assert q.returncode == 0, q.stderr
    (line,) = [x for x in q.stderr.splitlines() if "slow roll" in x]
    assert line.startswith(
        f"warning: {matrix}: line 3: key 'operating.spin_rpm': spin 600, 900 rpm are not above the slow roll of "
        f"the active calibration record {record}'s runout ([runout] spin_rpm = 900): "
    ), line
    assert "measure the runout below 600 rpm" in line
    # one spin, above the slow roll: nothing said; the same run with subtract_runout = false: nothing either
    matrix.write_text(MATRIX.format(spin="1500.0"))
    assert not [x for x in warning_lines(load_matrix(matrix), 50, load_rig(rig)) if "slow roll" in x]
    matrix.write_text(MATRIX.format(spin="600.0"))
    off = tmp_path / "off.toml"
    off.write_text(rig.read_text().replace("\n[transports]", "subtract_runout = false\n\n[transports]", 1))
    shutil.copytree(tmp_path / "calibration", tmp_path / "off" / "calibration")
    shutil.move(off, tmp_path / "off" / "rig.toml")
    assert not [
        x for x in warning_lines(load_matrix(matrix), 50, load_rig(tmp_path / "off" / "rig.toml")) if "slow" in x
    ]
    # the sweep says it at its start and run.log keeps it; so it does of a calibration older than
    # calibration_valid_days (here a tenth of a second: the runout just measured is older at the start)
    rig.write_text(rig.read_text().replace("\n[transports]", "\ncalibration_valid_days = 1e-6\n\n[transports]", 1))
    s = orbitrig(
        "sweep", "--sim", "--sim-config", "clean", "--config", str(rig), "--matrix", str(matrix), "--out", str(tmp_path / "run"),
        timeout=240,
    )  # fmt: skip
    assert s.returncode == 0, s.stderr
    assert s.stderr.count("is not above the slow roll") == 1, s.stderr
    log = (tmp_path / "run" / "run.log").read_text(encoding="utf-8")
    assert f"spin 600 rpm is not above the slow roll of the active calibration record {record}'s runout" in log
    aged = f"key 'calibration_valid_days': the active calibration record {record} holds runout 0 days old"
    assert s.stderr.count(aged) == 1 and f"warning: {rig}: line " in s.stderr, s.stderr
    assert aged in log and "older than calibration_valid_days = 1e-06; the run goes on" in log
    # and the run's results say it too: its provenance (run.json, run.h5, every export) names the
    # record's parts expired at the start, with their ages
    expired = "expired: past calibration_valid_days = 1e-06 at the run's start; runout 0 days old ("
    header = json.loads((tmp_path / "run" / "run.json").read_text(encoding="utf-8"))
    assert header["provenance"]["calibration_validity"].startswith(expired), header["provenance"]
    assert f"record {record})" in header["provenance"]["calibration_validity"]
    with h5py.File(tmp_path / "run" / "run.h5", "r") as f:
        assert str(f.attrs["calibration_validity"]).startswith(expired)
    e = orbitrig("export", str(tmp_path / "run"), "--format", "csv", "--out", str(tmp_path / "export"))
    assert e.returncode == 0, e.stderr
    with open(tmp_path / "export" / "provenance.csv", newline="", encoding="utf-8") as fh:
        assert dict(csv.reader(fh))["calibration_validity"].startswith(expired)
