"""A run whose own task is cancelled while it opens the drives (a fault elsewhere in the service
ends its task group): the drives' entry lets go of their link at once (drives/entry.py), so the
run sends both the emergency stop over a link of its own, as an abort during the opening gets
from its caller; drives found turning there (left so by another client, their watchdog off) do
not run on. run.log says what went out.

Real parts: the simulator in its own process (as `sweep --sim` runs it), the engine over Modbus
TCP, a client that leaves both drives turning (`RigDrives.release`), the simulator's own fault
injection holding the drives' answers while the run opens them (lifted at the cancel); and the
simulator in process with its drives over Modbus RTU on a pty, turned from their keypads."""

from __future__ import annotations

import asyncio
import time

import pytest

from drives.limits import DriveLimits
from drives.rig import RigDrives
from orbitrig import config as cfg
from rigunits import RPM
from support.sweep_helpers import SimulatorView, small_matrix, wait_for

pytestmark = pytest.mark.timeout(120)

# Spec control words, written out here (not imported from drives/) on purpose.
CW_EMERGENCY = 0x047B


async def _left_turning(url: str) -> None:
    """Both drives at speed and left so by a client that goes away, their watchdog off (0)."""
    limits = DriveLimits(max_spin=1500 * RPM, max_orbit=1500 * RPM)
    async with RigDrives(url, limits, comm_loss_timeout=0.0) as rig:
        await rig.set_speeds(600 * RPM, 300 * RPM)
        await rig.wait_settled(hold=0.1, timeout=30.0)
        rig.release()


async def test_a_run_cancelled_while_it_opens_the_drives_sends_both_the_emergency_stop(tmp_path):
    from orbitrig.cli.simulated_rig import simulated_rig
    from orbitrig.run.engine import RunEngine

    async with simulated_rig(40.0) as (sim, access):
        view = SimulatorView(sim)
        await _left_turning(access.endpoints.modbus_url)
        view.inject("modbus_timeout", on=True)  # the drives' entry waits for its first answer
        eng = RunEngine(cfg.load_rig(), out_dir=tmp_path / "run", access=access, confirm_mode="auto")
        run = asyncio.create_task(eng.run(small_matrix()))
        await wait_for(lambda: eng._opening is not None, 10, what="the opening")
        opening = eng._opening.get_coro().cr_frame.f_locals["self"]  # the run's RigIO, being entered
        await wait_for(lambda: opening.adc is not None, 10, what="the drives' entry")
        await asyncio.sleep(0.05)
        assert min(abs(w) for w in view.speeds) > 10.0, view.speeds  # both turning, nobody polls them
        t_cancel = time.monotonic()
        run.cancel()
        view.inject("clear")
        await asyncio.gather(run, return_exceptions=True)
        words = {dev: [cw for t, cw in view.drive(dev)["control_words"] if t >= t_cancel] for dev in (1, 2)}
        assert eng.io is None  # the run never held the drives
        for dev, after in words.items():
            assert CW_EMERGENCY in after, (dev, [hex(w) for w in after])
        await wait_for(lambda: max(abs(w) for w in view.speeds) < 1e-3, 20, what="standstill")
    text = (tmp_path / "run" / "run.log").read_text()
    assert "emergency stop (OFF3)" in text and "spin (id 1), orbit (id 2); standstill not confirmed" in text, text


async def test_over_rtu_the_emergency_stop_of_a_run_cancelled_while_opening_reaches_the_drive_that_answers(tmp_path):
    """The same on an RTU line (a pty opened exclusively: the stop's own link needs the port the
    cancelled opening let go of); the orbit drive at an id nobody answers (1 s request timeout), so
    the opening is slow, as on a real slow line: the spin drive has its OFF3 within 0.5 s."""
    import dataclasses

    from orbitrig.cli.simulated_rig import simulated_access
    from orbitrig.run.engine import RunEngine
    from sim.rig import SimRig

    rig = cfg.load_rig()
    rig = rig.model_copy(update={"drives": rig.drives.model_copy(update={"orbit_id": 9, "timeout_s": 1.0})})
    async with SimRig(speedup=20, adc_pty=False, modbus_rtu_pty=True) as sim_rig:
        url = f"rtu://{sim_rig.modbus_rtu_path}"
        sim_access = simulated_access(sim_rig)
        access = dataclasses.replace(sim_access, endpoints=dataclasses.replace(sim_access.endpoints, modbus_url=url))
        spin = sim_rig.drives[1]
        sim_rig.local_control(spin=100.0, orbit=-30.0, hand_back=True)  # turned from the keypads, no run
        await wait_for(lambda: abs(sim_rig.speeds[0]) > 10.0, 30, what="the spin drive turning")
        eng = RunEngine(rig, out_dir=tmp_path / "run", access=access, confirm_mode="auto")
        before = spin.last_request
        run = asyncio.create_task(eng.run(small_matrix()))
        try:
            await wait_for(lambda: spin.last_request != before, 30, what="the run's first request to the spin drive")
            t_cancel = time.monotonic()
            run.cancel()

            def off3() -> float | None:
                return min(
                    (s - t_cancel for s, cw in spin.control_words if s >= t_cancel and cw == CW_EMERGENCY), default=None
                )

            await wait_for(lambda: off3() is not None, 10, what="the emergency stop at the spin drive")
            assert off3() < 0.5, off3()
            await asyncio.wait_for(asyncio.gather(run, return_exceptions=True), 30)
        finally:
            if not run.done():
                run.cancel()
                await asyncio.gather(run, return_exceptions=True)
    text = (tmp_path / "run" / "run.log").read_text()
    assert "emergency stop (OFF3)" in text and "taken by spin (id 1)" in text, text
    assert "drives not confirmed stopped" in text, text  # the orbit id answers nobody: nothing says both stopped
