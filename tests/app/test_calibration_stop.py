"""A calibration step ends with both drives confirmed at standstill, or it fails: a stop
that is not confirmed within the drives' stop timeout fails the step (no record, nothing
said of drives stopped). The simulator in this process, its drives' ramp stop made slower
than the timeout through their DECEL_TIME register."""

from __future__ import annotations

import pytest

from orbitrig.cli.simulated_rig import simulated_access
from orbitrig.config import MPA, RPM, load_rig
from orbitrig.run.calibration import CalibrationSession, SlowRoll
from orbitrig.run.calibration_checks import CalibrationFailed

DECEL_TIME = 103  # the drives' register: 0.1 s per 3000 rpm along the ramp stop
ROLL = SlowRoll(spin=600 * RPM, recess_pressure=0.4826 * MPA, pressure_ratio=0.25, revolutions=5)


def _rig(stop_timeout_s: float):
    rig = load_rig()
    return rig.model_copy(update={"drives": rig.drives.model_copy(update={"stop_timeout_s": stop_timeout_s})})


@pytest.mark.parametrize("decel_counts, confirmed", [(None, True), (18000, False)])
async def test_a_step_whose_drives_are_not_confirmed_stopped_fails(decel_counts, confirmed):
    from sim.rig import SimRig

    notes: list[str] = []
    async with SimRig(speedup=20, adc_pty=False) as sim_rig:
        if decel_counts is not None:  # 1800 s per 3000 rpm: 600 rpm take 360 s (18 s wall); the timeout 5.05 s
            for drive in sim_rig.drives.values():
                drive.write(DECEL_TIME, [decel_counts])
        session = CalibrationSession(_rig(1.0), simulated_access(sim_rig), notes.append)
        if confirmed:
            async with session:
                await session.roll(ROLL)
            assert "both drives stopped" in notes
            assert all(abs(w) < 1e-3 for w in sim_rig.speeds), sim_rig.speeds
            return
        with pytest.raises(CalibrationFailed, match="drives not confirmed stopped") as failed:
            async with session:
                await session.roll(ROLL)
        assert "both drives stopped" not in notes, notes
        assert any(n.startswith("stopping the drives failed") for n in notes), notes
        assert any(abs(w) > 1.0 for w in sim_rig.speeds), sim_rig.speeds  # still ramping down
        assert failed.value.__cause__ is not None


async def test_a_signal_during_the_closing_ramp_leaves_the_operator_told_what_is_left_on_the_rig():
    """Every reading taken, the step ramps both drives down; a Ctrl-C during that ramp makes it the
    emergency stop, and once both are at standstill the operator is told (not asked) to take the
    load off: nothing is left on the rig unsaid."""
    import asyncio

    from sim.rig import SimRig

    from orbitrig.cli.calibrate_steps import OperatorLoads

    notes: list[str] = []
    async with SimRig(speedup=20, adc_pty=False) as sim_rig:
        for drive in sim_rig.drives.values():  # the ramp stop: 600 rpm in 6 s wall (the emergency one faster)
            drive.write(DECEL_TIME, [6000])
        session = CalibrationSession(_rig(60.0), simulated_access(sim_rig), notes.append)
        hands = OperatorLoads()  # the rig's hands: they ask the operator (never reached here)

        async def step() -> None:
            async with session:
                await session.roll(ROLL)
                async with session.applied(lambda: hands.apply_load(0.0, 0.0), "remove every calibration load", hands):
                    pass  # every load read

        task = asyncio.create_task(step())
        while not (sim_rig.drives[1].state == "off1_active" or task.done()):  # the closing ramp under way
            await asyncio.sleep(0.01)
        task.cancel()  # Ctrl-C
        with pytest.raises(asyncio.CancelledError):
            await task
        assert all(abs(w) < 1e-3 for w in sim_rig.speeds), sim_rig.speeds
    told = [n for n in notes if "remove every calibration load" in n]
    assert told == ["both drives at standstill: remove every calibration load (the step ended during the closing stop)"]
