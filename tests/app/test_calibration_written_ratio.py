"""A calibration step's slow roll averages at the spin turns of the speeds as written to the drives
(each REF rounded to its count, 0.15 rpm at SPEED_SCALE 3000 rpm), as a sweep's block does
(reduction.runout_slip.commanded_turns), not at the asked ratio: 1000 rpm spin over a 650 rpm orbit
spindle are written as 1000.05 and 649.95 rpm, 1.538657 turns a board revolution against the asked
1.538462, 1.3e-4 apart. (It used to take the asked ratio.)

Real parts: the simulator in this process behind its real Modbus server, A/D board and CAN node."""

from __future__ import annotations

import pytest

from orbitrig.cli.simulated_rig import simulated_access
from orbitrig.config import MPA, RPM, load_rig
from orbitrig.run.calibration import CalibrationSession, SlowRoll

pytestmark = pytest.mark.timeout(120)

ROLL = SlowRoll(spin=1000 * RPM, recess_pressure=0.4826 * MPA, pressure_ratio=0.25, revolutions=5, ratio=0.65)


async def test_the_slow_roll_averages_at_the_written_ratio():
    from sim.rig import SimRig

    async with SimRig(speedup=20, adc_pty=False) as sim_rig:
        async with CalibrationSession(load_rig(), simulated_access(sim_rig)) as session:
            await session.roll(ROLL)
            block = await session.average()
    assert block.turns is not None
    assert block.turns.commanded == pytest.approx(1000.05 / 649.95, rel=1e-9)
    assert abs(block.turns.commanded - 1 / ROLL.ratio) > 1e-4  # the asked ratio is another
