"""An abort that arrives while a run is still opening its drives' RTU link does not wait for the
opening: the run lets go of the port at once (the opening is cancelled, the run ends aborted) and
the emergency stop the abort then sends over a link of its own (orbitrig.service.idle_stop, as the
rig service does when no run holds the drives) reaches the drive that answers within 0.5 s.

Real parts: the simulator in process, its drives over Modbus RTU on a pty (a serial port opened
exclusively: one link at a time), turned from their keypads before the run; the orbit drive is
configured at an id nobody answers with a 1 s request timeout, so the run's opening of the drives
takes 2 s or more (two tries of its parameter read) - a slow line, as a real one can be."""

import asyncio
import dataclasses
import time

import pytest

from orbitrig.cli.simulated_rig import simulated_access
from orbitrig.config import load_rig
from orbitrig.run.engine import RunEngine
from orbitrig.run.rig_io import Endpoints
from orbitrig.service import idle_stop
from support.sweep_helpers import small_matrix, wait_for

pytestmark = pytest.mark.timeout(120)

CW_EMERGENCY = 0x047B  # the spec's emergency stop word, written out here (not imported from drives/)


async def test_an_abort_while_the_rtu_link_is_opened_stops_the_drive_that_answers_at_once(tmp_path):
    from sim.rig import SimRig

    rig = load_rig()
    rig = rig.model_copy(update={"drives": rig.drives.model_copy(update={"orbit_id": 9, "timeout_s": 1.0})})
    async with SimRig(speedup=20, adc_pty=False, modbus_rtu_pty=True) as sim_rig:
        url = f"rtu://{sim_rig.modbus_rtu_path}"
        sim_access = simulated_access(sim_rig)
        access = dataclasses.replace(sim_access, endpoints=dataclasses.replace(sim_access.endpoints, modbus_url=url))
        assert isinstance(access.endpoints, Endpoints)
        spin = sim_rig.drives[1]
        sim_rig.local_control(spin=100.0, orbit=-30.0, hand_back=True)  # turned from the keypads, no run
        await wait_for(lambda: abs(sim_rig.speeds[0]) > 10.0, 30, what="the spin drive turning")
        engine = RunEngine(rig, out_dir=tmp_path / "run", access=access, confirm_mode="auto")
        before = spin.last_request
        run = asyncio.create_task(engine.run(small_matrix()))
        try:
            await wait_for(lambda: spin.last_request != before, 30, what="the run's first request to the spin drive")
            t = time.monotonic()
            assert engine.request_abort(by="test") is False  # nothing reached the drives through the run
            stop = asyncio.create_task(idle_stop.emergency_stop(url, rig.drives, run))

            def off3() -> float | None:
                return min((s - t for s, cw in spin.control_words if s >= t and cw == CW_EMERGENCY), default=None)

            await wait_for(lambda: off3() is not None, 10, what="the emergency stop at the spin drive")
            assert off3() < 0.5, off3()
            outcome = await asyncio.wait_for(asyncio.shield(run), 30)
            assert outcome.status == "aborted", outcome.message
            error, _ = await asyncio.wait_for(stop, 30)
            assert error is not None and "delivered to spin (id 1) only" in error, error  # the orbit id answers nobody
        finally:
            if not run.done():
                run.cancel()
                await asyncio.gather(run, return_exceptions=True)
