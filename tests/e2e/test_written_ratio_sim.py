"""`orbitrig sweep --sim`: a block's commanded spin ratio is the ratio of the speeds as written to
the drives, each REF rounded to its count (docs/protocols/drive-modbus.md: 0.15 rpm at SPEED_SCALE
3000 rpm; 1000 rpm is written 1000.05 rpm, 650 rpm 649.95 rpm), not of the speeds the plan asked
for. Against the asked ratio the fit of a block's own ratio (reduction.runout_slip) was resolved with
no slip configured: 3 of the 5 fitted blocks of this list (6 to 8 u off, 1.53865 against 1000/650 =
1.53846), so their runout was placed, their u and the table's taken, at a ratio the drives were not
given. Against the written ratio none is (within 1.3 u), and a spin 0.5 % fast (the simulator's
drive holds it to 3 rpm, 0.3 % at 1000 rpm) is resolved in all 5, 0.30 % off. Real parts: a
subprocess, the simulator's drives over Modbus TCP, its A/D board's frames."""

from __future__ import annotations

import json
import math

import h5py
import numpy as np
import pytest

from orbitrig.store.reader import read_run
from support.cli_helpers import orbitrig
from support.paths import ROOT

pytestmark = pytest.mark.timeout(180)
RPM = 2 * math.pi / 60
STEP = 3000 / 20000  # rpm per REF count at the drives' default SPEED_SCALE
RATIOS = [0.363, 0.471, 0.65, 0.733, 0.871, 1.139]  # Omega/omega, the tables' row order; 1.139: no spin content to fit

MATRIX = f"""name = "written"
description = "the ratio as written to the drives"
revolutions = 100

[operating]
spin_rpm = [1000.0]
recess_pressure_mpa = [0.4826]
pressure_ratio = [0.4]
static_eccentricity = [0.0]
dynamic_eccentricity = [0.096]

[orbit]
ratios = {RATIOS}
directions = ["forward"]

[[models]]
model = "kcd11"
"""


def _sweep(tmp_path, spin_speed_error: float):
    """The sweep of MATRIX on the paper's scenario with the spin drive ``spin_speed_error`` fast:
    (its points' runout_turns, its blocks' frequencies)."""
    matrix, scenario, out = tmp_path / "written.toml", tmp_path / "scenario.toml", tmp_path / "run"
    matrix.write_text(MATRIX)
    scenario.write_text((ROOT / "config/sim.toml").read_text() + f"\n[drives]\nspin_speed_error = {spin_speed_error}\n")
    args = ("--matrix", str(matrix), "--sim-config", str(scenario), "--out", str(out), "--speedup", "40")
    p = orbitrig("sweep", "--sim", *args, timeout=150)
    assert p.returncode == 0, p.stdout + p.stderr
    with h5py.File(out / "run.h5") as f:
        turns = json.loads(f["points/0000/runout_turns"].attrs["json"])
    return turns, read_run(out).complete_points[0].frequencies


def _written(rpm: float) -> float:
    """rad/s of ``rpm`` as its REF count gives it."""
    return round(rpm / STEP) * STEP * RPM


def test_with_no_slip_no_blocks_fitted_ratio_is_resolved_against_the_ratio_written(tmp_path):
    turns, freqs = _sweep(tmp_path, 0.0)
    for f, ratio in zip(freqs, RATIOS):  # stored beside the planned orbit, each REF's count
        assert f.written == pytest.approx((_written(1000), _written(ratio * 1000)), rel=1e-12)
        assert f.orbit == pytest.approx(ratio * 1000 * RPM, rel=1e-12)
    commanded = np.array(turns["commanded"])
    assert commanded == pytest.approx([_written(1000) / _written(r * 1000) for r in RATIOS], rel=1e-12)
    assert commanded[2] == pytest.approx(1000.05 / 649.95, rel=1e-12)  # asked: 1000 / 650
    fitted = [i for i, u in enumerate(turns["u"]) if u is not None]
    assert 5 not in fitted and len(fitted) >= 3  # 1.139: no probe's spin harmonic stands out of its noise
    # against the ratio asked, 3 of 5 were resolved, 6 to 8 u off; against the written one a block is
    # resolved (beyond RESOLVED = 3 u) by chance alone with p = 0.27 %: one such block is allowed
    off = [abs(turns["fitted"][i] - commanded[i]) / turns["u"][i] for i in fitted]
    assert sum(turns["resolved"]) <= 1 and max(off) < 4.5, off
    for i, resolved in enumerate(turns["resolved"]):
        assert turns["used"][i] == (turns["fitted"][i] if resolved else turns["commanded"][i])


def test_a_spin_turning_fast_is_still_resolved_against_the_ratio_written(tmp_path):
    turns, _ = _sweep(tmp_path, 0.005)
    fitted = [i for i, u in enumerate(turns["u"]) if u is not None]
    assert len(fitted) >= 3 and all(turns["resolved"][i] for i in fitted)
    # the drive holds its error to 3 rpm: 0.3 % at 1000 rpm once settled; on loaded cores a block of
    # the sped-up board may still see the orbit drive's last rpm of its ramp (wall-clock time, within
    # the drives' 5 rpm at-setpoint band): one block 0.19 % or 0.37 % seen there, the others 0.30 %
    slips = [turns["fitted"][i] / turns["commanded"][i] - 1 for i in fitted]
    assert float(np.median(slips)) == pytest.approx(0.003, abs=5e-4), slips
    assert all(turns["used"][i] == turns["fitted"][i] for i in fitted)
