"""A signal during a calibration step's final ramp stop does not cut the wait for standstill
short: it makes the stop an emergency stop (OFF3), and the step ends interrupted only once both
drives are confirmed at standstill; a stop that still cannot be confirmed fails the step
("drives not confirmed stopped"), whatever the signal. A real SIGTERM to this process through
`run_until_signal` (as `orbitrig calibrate` runs a step), the simulator in this process, its
drives' ramp made slower through their DECEL_TIME register."""

from __future__ import annotations

import asyncio
import os
import signal

import pytest

from orbitrig.cli.signals import Interrupted, run_until_signal
from orbitrig.cli.simulated_rig import simulated_access
from orbitrig.config import MPA, RPM, load_rig
from orbitrig.run.calibration import CalibrationSession, SlowRoll
from orbitrig.run.calibration_checks import CalibrationFailed

pytestmark = pytest.mark.timeout(90)
DECEL_TIME = 103  # the drives' register: 0.1 s per 3000 rpm along the ramp stop (OFF3: a tenth)
CW_RAMP_STOP, CW_EMERGENCY = 0x047E, 0x047B
ROLL = SlowRoll(spin=600 * RPM, recess_pressure=0.4826 * MPA, pressure_ratio=0.25, revolutions=5)


def _rig(stop_timeout_s: float):
    rig = load_rig()
    return rig.model_copy(update={"drives": rig.drives.model_copy(update={"stop_timeout_s": stop_timeout_s})})


def _step(speedup: float, decel_counts: int, stop_timeout_s: float, seen: dict):
    """A calibration step that rolls and ends (the final ramp stop); SIGTERM once both drives
    ramp. `seen`: the notes, and both drives' rpm and last control word as the step's way out ends."""

    async def step() -> None:
        from sim.rig import SimRig

        async with SimRig(speedup=speedup, adc_pty=False) as sim_rig:
            drives = sim_rig.drives
            for drive in drives.values():
                drive.write(DECEL_TIME, [decel_counts])

            async def signal_in_the_ramp() -> None:
                while not all(d.read(0, 1)[0] == CW_RAMP_STOP for d in drives.values()):
                    await asyncio.sleep(0.005)
                os.kill(os.getpid(), signal.SIGTERM)

            session = CalibrationSession(_rig(stop_timeout_s), simulated_access(sim_rig), seen["notes"].append)
            try:
                async with session:
                    await session.roll(ROLL)
                    asyncio.get_running_loop().create_task(signal_in_the_ramp())
            finally:
                for d in drives.values():
                    d.advance()
                seen["rpm"] = [d.actual_rpm for d in drives.values()]
                seen["cw"] = [d.read(0, 1)[0] for d in drives.values()]

    return step


def test_a_signal_in_the_final_ramp_is_an_emergency_stop_waited_for():
    seen: dict = {"notes": []}
    with pytest.raises(Interrupted) as stopped:  # 600 rpm take 40 s along the ramp (2 s wall), 4 s along OFF3
        run_until_signal(_step(20.0, 2000, 30.0, seen), "calibrate")
    assert stopped.value.sig == signal.SIGTERM
    assert seen["rpm"] == [0.0, 0.0] and seen["cw"] == [CW_EMERGENCY, CW_EMERGENCY], seen
    assert any(n.startswith("both drives stopped") for n in seen["notes"]), seen["notes"]


def test_a_signal_in_a_final_ramp_never_confirmed_fails_the_step():
    seen: dict = {"notes": []}
    # the longest ramp: 600 rpm take 360 s, 36 s along OFF3 (9 s wall at 4 x); the timeout 5.25 s
    with pytest.raises(CalibrationFailed, match="drives not confirmed stopped"):
        run_until_signal(_step(4.0, 18000, 1.0, seen), "calibrate")
    assert not any(n.startswith("both drives stopped") for n in seen["notes"]), seen["notes"]
    assert all(abs(rpm) > 1.0 for rpm in seen["rpm"]) and seen["cw"] == [CW_EMERGENCY, CW_EMERGENCY], seen
