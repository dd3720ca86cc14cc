"""A calibration step ends with both drives confirmed at standstill, or it fails: a stop
that is not confirmed within the drives' stop timeout fails the step (no record, nothing
said of drives stopped). The simulator in this process, its drives' ramp stop made slower
than the timeout through their DECEL_TIME register."""

from __future__ import annotations

import pytest

from orbitrig.cli.simulated_rig import simulated_access
from orbitrig.config import MPA, RPM, load_rig
from orbitrig.run.calibration import CalibrationFailed, CalibrationSession, SlowRoll

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
