"""A calibration step's slow roll starts only once the recess pressure and the pressure ratio (the
supply) read from CAN meet the step's, as a sweep checks them before it spins: pressures left
off (a regulator not set, the supply at another pressure) fail the step after the settle window,
naming the pressure, with no drive ever commanded to run. (It used to start both spindles at
once, whatever the pressures read.)

Real parts: the simulator in this process behind its real Modbus server and CAN node (python-can
`virtual` bus); the operator's hands set the orbit radius to zero as asked but leave one pressure
off."""

from __future__ import annotations

import time

import pytest

from orbitrig.cli.simulated_rig import simulated_access
from orbitrig.config import MPA, RPM, load_rig
from orbitrig.run.calibration import CalibrationSession, SlowRoll
from orbitrig.run.calibration_checks import CalibrationFailed

pytestmark = pytest.mark.timeout(120)

ROLL = SlowRoll(spin=600 * RPM, recess_pressure=0.4826 * MPA, pressure_ratio=0.25, revolutions=5)
CW_RUN = 0x047F  # spec control word, written out on purpose


class PressureLeftOff:
    """Hands that do as asked but leave one pressure at `left` (Pa, or the ratio)."""

    def __init__(self, hands, **left: float):
        self.hands, self.left = hands, left

    async def set_manual(self, **settings: float) -> None:
        await self.hands.set_manual(**{**settings, **self.left})


@pytest.mark.parametrize(
    ("left", "words"),
    [
        ({"recess_pressure": 0.30 * MPA}, "recess pressure 0.3000 MPa, want 0.4826 MPa"),
        ({"pressure_ratio": 0.40}, "pressure ratio 0.400, want 0.25"),
    ],
    ids=["recess", "supply"],
)
async def test_no_slow_roll_with_the_pressures_off(left, words):
    from sim.rig import SimRig

    notes: list[str] = []
    async with SimRig(speedup=20, adc_pty=False) as sim_rig:
        access = simulated_access(sim_rig)
        access = type(access)(**{**access.__dict__, "hands": PressureLeftOff(access.hands, **left)})
        session = CalibrationSession(load_rig(), access, notes.append)
        t0 = time.monotonic()
        with pytest.raises(CalibrationFailed, match="pressures not met before the slow roll: ") as failed:
            async with session:
                await session.roll(ROLL)
        took = time.monotonic() - t0
        assert words in str(failed.value) and str(failed.value).endswith("slow roll not started"), failed.value
        assert not any(n.startswith("slow roll:") for n in notes), notes
        assert max(abs(w) for w in sim_rig.speeds) == 0.0, sim_rig.speeds
        for drive in (1, 2):  # never commanded to run
            assert CW_RUN not in [cw for _, cw in sim_rig.drives[drive].control_words]
        assert 3.0 <= took < 30.0, took  # the settle window (3 wall s at speed-up 20), then the step ends


async def test_the_slow_roll_starts_with_the_pressures_met():
    from sim.rig import SimRig

    notes: list[str] = []
    async with SimRig(speedup=20, adc_pty=False) as sim_rig:
        async with CalibrationSession(load_rig(), simulated_access(sim_rig), notes.append) as session:
            await session.roll(ROLL)
            assert all(abs(w) > 0.9 * ROLL.spin for w in sim_rig.speeds), sim_rig.speeds
        assert notes.index("pressures verified before the slow roll") < next(
            i for i, n in enumerate(notes) if n.startswith("slow roll:")
        ), notes
