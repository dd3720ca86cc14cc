"""`orbitrig calibrate runout` on the rig code path asks for the slow roll's manual settings (orbit
radius 0, static eccentricity 0, the step's pressures) with both drives at standstill and starts
the spindles only once the operator confirms; nobody to confirm (standard input closed): the step
fails, no drive started, no record. An orbit left set from a sweep would otherwise be recorded as
runout (9 um of orbit against 0.225 um of runout).

Real parts: the simulator in its own process (`orbitrig sim`, default scenario: runout 0.225 um
at 1x, 0.09 um at 2x spin) behind a copy of the lab's rig.toml; the test plays the operator."""

from __future__ import annotations

import re

import numpy as np
import pytest

from orbitrig.config import read_record
from support.calibrate_operator import Calibrate, Simulator, confirm_manual

pytestmark = pytest.mark.timeout(300)
LEFT_ORBIT = 9e-6  # m, eps_d 0.15 of the 60 um clearance: an orbit left from a sweep
RUNOUT_ARGS = ("runout", "--revolutions", "20")


@pytest.fixture
def rig(tmp_path):
    """(simulator with an orbit left set, rig.toml reaching it, the records' folder)."""
    sim = Simulator()
    try:
        sim.call(
            "set_manual",
            orbit_radius=LEFT_ORBIT,
            static_eccentricity=0.0,
            recess_pressure=0.4826e6,
            pressure_ratio=0.25,
        )
        config = sim.rig_config(tmp_path)
        yield sim, config, config.parent / "calibration"
    finally:
        sim.close()


def _names(records) -> list[str]:
    return sorted(p.name for p in records.iterdir())


def test_runout_without_a_confirmation_starts_no_drive_and_writes_nothing(rig):
    sim, config, records = rig
    before = _names(records)
    step = Calibrate(config, RUNOUT_ARGS)
    try:
        step.proc.stdin.close()  # no terminal: nobody can confirm
        code = step.ended(sim)
    finally:
        step.close()
    err = step.stderr()
    assert code == 1, err
    assert "set orbit radius 0 \u00b5m, static eccentricity 0, recess pressure 0.4826 MPa" in step.stdout()
    assert "nobody can confirm at the terminal" in err and "spindles not started" in err, err
    assert "slow roll: spin" not in err, err  # the drives were never brought to the slow roll
    assert sim.rpm() == (0.0, 0.0)
    assert _names(records) == before and "Traceback" not in err


def test_runout_asks_for_the_orbit_radius_before_the_drives_start(rig):
    sim, config, records = rig
    before = _names(records)
    step = Calibrate(config, RUNOUT_ARGS)
    try:
        prompt = confirm_manual(sim, step)  # the operator sets the orbit radius to 0 as asked
        code = step.ended(sim)
    finally:
        step.close()
    assert prompt.endswith("for the run without orbit (it starts both spindles),"), prompt
    assert code == 0, step.stderr()
    (new,) = sorted(set(_names(records)) - set(before))
    rec, _ = read_record(records, new.removesuffix(".toml"))
    for p in ("x_a", "y_a", "x_b", "y_b"):
        h1, h2 = np.abs(rec.runout.phasors(p))
        assert h1 == pytest.approx(0.225e-6, abs=0.05e-6), (p, h1)
        assert h2 == pytest.approx(0.09e-6, abs=0.05e-6), (p, h2)
    assert re.search(r"x_a: runout 1x 0\.\d+ \u00b5m, 2x 0\.\d+ \u00b5m", step.stdout()), step.stdout()
    assert " um" not in step.stdout()
