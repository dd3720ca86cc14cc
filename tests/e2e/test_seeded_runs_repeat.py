"""Two runs of one seeded simulator scenario (docs/simulator.md, "What a seed fixes"): the truth
they record agrees (its operating points are the seed's, the orbit speeds measured) and the
identified coefficients agree within the stated tolerance, 5 combined standard deviations of the
two fits (which revolutions a block averages follows the wall clock, so two runs are two draws of
the same seeded rig, not one). The old code's runs differed as much: this holds the tolerance the
docs state; tests/sim/test_sim_reproducible.py holds what the seed fixes to the bit."""

from __future__ import annotations

import asyncio
import math

import numpy as np
import pytest

import orbitrig
from orbitrig import config as cfg
from orbitrig.cli.simulated_rig import simulated_rig
from orbitrig.run.engine import RunEngine
from sim.scenario_files import load_sim_config

from support.paths import ROOT
from support.rig_configs import patient_rig

MATRIX = """name = "repeat"
revolutions = 12
[operating]
spin_rpm = [1000.0]
recess_pressure_mpa = [0.4826]
pressure_ratio = [0.25]
static_eccentricity = [0.0]
dynamic_eccentricity = [0.04]
[orbit]
ratios = [0.363, 0.677, 1.139]
directions = ["forward", "backward"]
[[models]]
model = "kcd11"
"""
KEYS = ("Kxx", "Kxy", "Kyx", "Kyy", "Cxx", "Cxy", "Cyx", "Cyy", "Dxx", "Dxy", "Dyy")
pytestmark = pytest.mark.timeout(240)

#: combined standard deviations two runs of one seed may differ by: 22 coefficients (2 systems x 11)
#: each beyond 4 in 6e-5 of the runs made up to 1.4e-3 a run; beyond 5: 6e-7 each, 1.3e-5 a run
TOLERANCE = 5.0


async def _run(out):
    sim_cfg = load_sim_config(ROOT / "config/sim/clean.toml")
    sim_cfg.seed = 7
    async with simulated_rig(40.0, config=sim_cfg) as (_, access):
        eng = RunEngine(patient_rig(), out_dir=out, access=access, confirm_mode="auto")
        await asyncio.wait_for(eng.run(cfg.matrix_from_text(MATRIX, "repeat.toml")), 120)
    run = orbitrig.open_run(out)
    return run.coefficients.set_index(["lms"]), run.truth(0)


def test_two_runs_of_one_seed_agree_within_the_stated_tolerance(tmp_path):
    (a, truth_a), (b, truth_b) = (asyncio.run(_run(tmp_path / name)) for name in ("a", "b"))
    # the rig's truth is the seed's; it is evaluated at each block's measured orbit speed, which the
    # speed ripple at the block's (wall-clock) time moves by a few 1e-4
    assert np.array_equal(truth_a["orbit_hz"], truth_b["orbit_hz"])
    for part in ("Z_re", "Z_im"):
        scale = np.abs(truth_a[part]).max()
        assert np.allclose(truth_a[part], truth_b[part], rtol=0, atol=2e-3 * scale), part
    ra, rb = a[a["model"] == "kcd11"], b[b["model"] == "kcd11"]
    assert sorted(ra.index) == sorted(rb.index) == ["piezo", "strain"]
    for lms in ("piezo", "strain"):
        for key in KEYS:
            x, y = float(ra.loc[lms, key]), float(rb.loc[lms, key])
            s = math.hypot(float(ra.loc[lms, f"{key}_std"]), float(rb.loc[lms, f"{key}_std"]))
            assert abs(x - y) <= TOLERANCE * s, (lms, key, x, y, s)
