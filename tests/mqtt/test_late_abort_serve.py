"""A second signal to `orbitrig serve` after the run has closed the drives is not dropped.

The first signal shuts the service down: the run stops at once, and its cleanup cannot confirm
the drives stopped (their ramp stop lasts minutes): "drives not confirmed stopped". A second
signal (`RigService.abort_run`, as `orbitrig serve` calls it) then finds no run that holds the
drives, while the run records its end (faulted) or once it has ended and the service is still
leaving: both drives get the emergency stop (OFF3) over the service's own link, as an MQTT abort
no run carries out, and the log says which drives took it.

Real parts: mosquitto with the shipped ACL and accounts, the service `orbitrig serve --sim`
builds (in process, on the simulator: drives over real Modbus TCP). Injected: the broker's
acknowledgement of the service's last messages held 3 s (a loaded broker), which keeps the
service leaving while the second signal comes.
"""

from __future__ import annotations

import asyncio
import logging
import time

import pytest

from drives import registers as R
from orbitrig.config import load_rig
from orbitrig.run.engine import StatusEvent
from orbitrig.run.states import RunState
from support.mqtt_helpers import RigClient, service_in_process, wait
from support.polling import until

pytestmark = pytest.mark.timeout(240)

DECEL_TIME = 103  # the drives' register: 0.1 s for SPEED_SCALE (3000) rpm along the ramp stop
SECOND = "SIGTERM; a second signal while shutting down"  # as orbitrig.cli.serve words it


class SlowDrained(asyncio.Event):
    """The broker's acknowledgements of the service's last messages take 3 s (a loaded broker)."""

    async def wait(self):
        await asyncio.sleep(3.0)
        return await super().wait()


@pytest.mark.parametrize("when", ["run-recording-its-end", "run-ended-service-leaving"])
async def test_a_second_signal_after_the_run_closed_the_drives_sends_the_emergency_stop(broker, tmp_path, caplog, when):
    from sim.rig import SimRig

    caplog.set_level(logging.WARNING, logger="orbitrig.service.rig_service")
    rig = load_rig()
    rig = rig.model_copy(update={"drives": rig.drives.model_copy(update={"stop_timeout_s": 2.0})})
    # from 190 rpm a ramp stop of 114 s simulated, 11 s here: twice what the run's cleanup waits
    async with SimRig(speedup=10.0, adc_pty=False) as sim_rig:
        for drive in sim_rig.drives.values():
            drive.write(DECEL_TIME, [18000])
        svc = service_in_process(broker.url, tmp_path, f"late-{when}", rig=rig, sim_rig=sim_rig, abort=False)
        svc.link.drained = SlowDrained()
        shutdown = asyncio.Event()
        task = asyncio.create_task(svc.serve(shutdown))
        rc = RigClient(broker, f"late-{when}")
        loop = asyncio.get_running_loop()
        second_at: list[float] = []
        run_active_then: list[bool] = []
        faulted: list[str] = []

        def second_signal() -> None:
            second_at.append(time.monotonic())
            run_active_then.append(svc.run_active)
            svc.abort_run(SECOND)

        def at_the_fault(ev) -> None:  # the run has closed the drives and records its end
            if isinstance(ev, StatusEvent) and ev.state == RunState.FAULTED and not faulted:
                faulted.append(ev.message or "")
                if when == "run-recording-its-end":
                    loop.call_soon_threadsafe(second_signal)

        try:
            await wait(rc.status, "idle")
            assert (await wait(rc.command, {"cmd": "start", "matrix": "quick"}))["ok"] is True
            svc._engine.subscribe(at_the_fault)
            await until(lambda: min(abs(w) for w in sim_rig.speeds) > 20.0, 120, "both drives turning")
            shutdown.set()  # the first signal: the run stops at once
            if when == "run-ended-service-leaving":
                await until(lambda: not svc.run_active, 120, "the run's end recorded")
                assert not task.done()
                second_signal()
            await asyncio.wait_for(asyncio.shield(task), 120)
        finally:
            rc.close()
            shutdown.set()
            if not task.done():
                svc.abort_run("test over")
                await asyncio.wait_for(asyncio.gather(task, return_exceptions=True), 120)
        assert faulted and "drives not confirmed stopped" in faulted[0], faulted
        assert run_active_then == [when == "run-recording-its-end"], run_active_then
        for device, drive in sim_rig.drives.items():
            words = [cw for t, cw in drive.control_words if t >= second_at[0]]
            assert R.CW_EMERGENCY_STOP in words, (device, [hex(w) for w in words])
    assert f"abort ({SECOND}): emergency stop (OFF3) sent to both drives" in caplog.text, caplog.text
