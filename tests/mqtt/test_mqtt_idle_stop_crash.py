"""The drives stop on a service's way out after a fault: a stop that no run carries out is
delivered even if the service fails meanwhile (an abort with no run holding the drives sends both
the emergency stop (OFF3) over a link of the service's own; a bug in another of the service's
tasks while that stop is under way ends the service, its task group cancelling what it holds, yet
the stop words still go out to both drives, and the service is left only once the stop is over);
a run under way when the service fails stops its drives (OFF3, standstill) before its end is
recorded and before the service is left, also when it was already ramping them down (the
shutdown's stop): its ramp becomes the emergency stop, not cut short.

Real parts: mosquitto with the shipped ACL and accounts, the service `orbitrig serve --sim` builds
(in process, on the simulator, over Modbus TCP), the simulator's own fault injection (its next
request unanswered: the spin drive's word times out once, so the stop is under way when the bug
strikes), the run's run.log. The one injected part: the bug, a task of the service's that raises."""

from __future__ import annotations

import asyncio
import time

import pytest

from drives import registers as R
from support.mqtt_helpers import RigClient, service_in_process, wait
from support.polling import until
from test_mqtt_abort_always_sent import publish_abort, standstill


class ABug(RuntimeError):
    """What a bug in one of the service's tasks raises."""


async def bug() -> None:
    raise ABug("a bug in one of the service's tasks")


async def _bug_ends_the_service(svc, serving, sim_rig, tmp_path) -> str:
    """A bug in one of the service's tasks ends it (the ExceptionGroup holds the bug): both drives
    at standstill when it has left, each having taken the emergency stop word since the bug; the
    run's run.log text."""
    t_bug = time.monotonic()
    assert svc._tg is not None
    svc._tg.create_task(bug(), name="buggy")
    with pytest.raises(ExceptionGroup) as ended:
        await asyncio.wait_for(asyncio.shield(serving), 120)
    assert ended.group_contains(ABug)
    assert standstill(sim_rig), sim_rig.speeds  # stopped before the service left
    for device, drive in sim_rig.drives.items():
        words = [cw for t, cw in drive.control_words if t >= t_bug]
        assert R.CW_EMERGENCY_STOP in words, (device, [hex(w) for w in words])
    (log,) = (tmp_path / "runs").glob("*/run.log")
    return log.read_text()


async def test_a_crash_during_an_idle_abort_does_not_cut_its_stop_words_short(broker, tmp_path):
    from sim.rig import SimRig

    async with SimRig(speedup=20.0, adc_pty=False) as sim_rig:
        svc = service_in_process(broker.url, tmp_path, "crash-rig", sim_rig=sim_rig, reconnect_initial=0.2)
        shutdown = asyncio.Event()
        serving = asyncio.create_task(svc.serve(shutdown))
        rc = RigClient(broker, "crash-rig")
        try:
            await wait(rc.status, "idle")
            await until(lambda: svc.abort_link.up, 30, "the abort connection up")
            sim_rig.local_control(spin=50.0, orbit=-30.0, hand_back=True)  # someone at the drives, no run
            await until(lambda: min(abs(w) for w in sim_rig.speeds) > 10.0, 30, "both drives turning")

            sim_rig.modbus_servers[0].drop_next(1)  # the stop's first word (the spin drive's) times out
            t_abort = time.monotonic()
            publish_abort(rc, "crash-abort")
            await until(lambda: svc._idle_stop is not None, 15, "the abort's stop under way")
            assert not svc._idle_stop.done()

            assert svc._tg is not None
            svc._tg.create_task(bug(), name="buggy")
            with pytest.raises(ExceptionGroup) as ended:
                await asyncio.wait_for(asyncio.shield(serving), 60)
            assert ended.group_contains(ABug)
            for device, drive in sim_rig.drives.items():  # both got the word before the service left
                words = [cw for t, cw in drive.control_words if t >= t_abort]
                assert R.CW_EMERGENCY_STOP in words, (device, [hex(w) for w in words])
            await until(lambda: standstill(sim_rig), 30, "both drives at standstill")
        finally:
            rc.close()
            shutdown.set()
            await asyncio.wait_for(asyncio.gather(serving, return_exceptions=True), 120)


async def test_a_crash_during_a_run_stops_its_drives_before_the_service_leaves(broker, tmp_path):
    """A bug in another of the service's tasks during a run: the run is cancelled with the group,
    its cleanup stops both drives (the emergency stop) and waits for standstill before run.log's
    last line; the service is left only after that."""
    from sim.rig import SimRig

    async with SimRig(speedup=20.0, adc_pty=False) as sim_rig:
        svc = service_in_process(broker.url, tmp_path, "crash-run-rig", sim_rig=sim_rig, reconnect_initial=0.2)
        shutdown = asyncio.Event()
        serving = asyncio.create_task(svc.serve(shutdown))
        rc = RigClient(broker, "crash-run-rig")
        try:
            await wait(rc.status, "idle")
            assert (await wait(rc.command, {"cmd": "start", "matrix": "long"}))["ok"] is True
            await wait(rc.status, "running")
            await until(lambda: min(abs(w) for w in sim_rig.speeds) > 50.0, 60, "both drives turning")
            text = await _bug_ends_the_service(svc, serving, sim_rig, tmp_path)
            assert "drives: emergency stop (OFF3)" in text, text
            assert text.index("drives: emergency stop (OFF3)") < text.rindex("aborted"), text
        finally:
            rc.close()
            shutdown.set()
            await asyncio.wait_for(asyncio.gather(serving, return_exceptions=True), 120)


async def test_a_crash_during_a_runs_closing_ramp_makes_it_the_emergency_stop_before_the_service_leaves(
    broker, tmp_path
):
    """The shutdown stops the run with a ramp (OFF1, a slow DECEL_TIME here); a bug in another of
    the service's tasks during that ramp cancels the run with the group: its ramp becomes the
    emergency stop, still waited for at standstill before the run's end is recorded and the
    service is left, and the run ends aborted."""
    from sim.rig import SimRig

    async with SimRig(speedup=20.0, adc_pty=False) as sim_rig:
        for drive in sim_rig.drives.values():
            drive.write(R.DECEL_TIME, [1800])  # a ramp stop of about 60 s simulated (3 s here)
        svc = service_in_process(broker.url, tmp_path, "crash-ramp-rig", sim_rig=sim_rig, reconnect_initial=0.2)
        shutdown = asyncio.Event()
        serving = asyncio.create_task(svc.serve(shutdown))
        rc = RigClient(broker, "crash-ramp-rig")
        try:
            await wait(rc.status, "idle")
            assert (await wait(rc.command, {"cmd": "start", "matrix": "long"}))["ok"] is True
            await wait(rc.status, "running")
            await until(lambda: min(abs(w) for w in sim_rig.speeds) > 50.0, 60, "both drives turning")
            shutdown.set()  # the run stops at once with a ramp
            await until(lambda: svc._engine is not None and svc._engine.state == "stopping", 30, "the closing ramp")
            await asyncio.sleep(0.3)
            assert min(abs(w) for w in sim_rig.speeds) > 10.0, sim_rig.speeds  # still ramping down
            text = await _bug_ends_the_service(svc, serving, sim_rig, tmp_path)
            assert "drives: emergency stop (OFF3) after an abort during the ramp" in text, text
            assert "run cancelled while stopping" in text, text
        finally:
            rc.close()
            shutdown.set()
            await asyncio.wait_for(asyncio.gather(serving, return_exceptions=True), 120)
