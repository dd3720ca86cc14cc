"""A run the service's bounded wait (shutdown_timeout) cancels while its drives' closing stop is
under way: the stop is not cut short (the ramp becomes the emergency stop, still waited for at
standstill, orbitrig.run.safe_stop), so the run's last status says how that stop ended: both
drives confirmed at standstill here, not "drives' stop not confirmed".

Real parts: mosquitto with the shipped ACL and accounts, the service `orbitrig serve --sim` builds
(in process, on the simulator, over Modbus TCP) with a wait of 1 s for the run's end, a slow
DECEL_TIME (the closing ramp about 3 s) so that the wait runs out in the ramp, the run's run.log."""

from __future__ import annotations

import asyncio

import pytest

from drives import registers as R
from support.mqtt_helpers import RigClient, service_in_process, wait
from support.polling import until
from test_mqtt_abort_always_sent import standstill

pytestmark = pytest.mark.timeout(180)


async def test_a_run_cancelled_in_its_closing_stop_says_the_standstill_confirmed(broker, tmp_path):
    from sim.rig import SimRig

    async with SimRig(speedup=20.0, adc_pty=False) as sim_rig:
        for drive in sim_rig.drives.values():
            drive.write(R.DECEL_TIME, [1800])  # a ramp stop of about 60 s simulated (3 s here)
        svc = service_in_process(
            broker.url, tmp_path, "cut-stop-rig", sim_rig=sim_rig, reconnect_initial=0.2, shutdown_timeout=1.0
        )  # a wait of 1 s for a run's end
        shutdown = asyncio.Event()
        serving = asyncio.create_task(svc.serve(shutdown))
        rc = RigClient(broker, "cut-stop-rig")
        try:
            await wait(rc.status, "idle")
            mark = rc.watch.mark()
            assert (await wait(rc.command, {"cmd": "start", "matrix": "long"}))["ok"] is True
            run_id = (await wait(rc.status, "running"))["run_id"]
            await until(lambda: min(abs(w) for w in sim_rig.speeds) > 50.0, 60, "both drives turning")
            shutdown.set()  # the run stops at once with a ramp; the service waits 1 s for its end
            await asyncio.wait_for(asyncio.shield(serving), 120)
            assert standstill(sim_rig), sim_rig.speeds
            ended = await wait(rc.status, lambda s: s["state"] == "idle" and s.get("run_id") == run_id, 30, mark)
            message = ended["message"]
            said = "; cancelled after 1 s, its drives' closing stop not ended; that stop: standstill confirmed"
            assert said in message, message
            assert "not confirmed" not in message, message
            (log,) = (tmp_path / "runs").glob("*/run.log")
            text = log.read_text()
            assert "drives: emergency stop (OFF3) after an abort during the ramp; standstill after" in text, text
        finally:
            rc.close()
            shutdown.set()
            await asyncio.wait_for(asyncio.gather(serving, return_exceptions=True), 120)


async def test_a_run_cancelled_in_its_closing_stop_with_every_point_stored_says_all_points_completed(broker, tmp_path):
    """The service's run task cancelled as its run closes, every point measured and stored and no
    stop or abort asked (the service shutting down, a fault elsewhere ending its task group): the
    cancellation is an abort, the run ends aborted, and its end message starts with 'all points
    completed; ' as every stopped or aborted end with every point complete does (orbitrig.run.ending),
    in run.h5, run.log and the service's closing status (before: 'run cancelled while stopping (all
    points completed)', with no prefix)."""
    from orbitrig.run.engine import StatusEvent
    from orbitrig.store.reader import read_run
    from sim.rig import SimRig

    async with SimRig(speedup=40.0, adc_pty=False) as sim_rig:
        svc = service_in_process(broker.url, tmp_path, "cancel-end-rig", sim_rig=sim_rig, reconnect_initial=0.2)
        shutdown = asyncio.Event()
        serving = asyncio.create_task(svc.serve(shutdown))
        rc = RigClient(broker, "cancel-end-rig")
        cancelled: list[str] = []

        def cancel_as_it_closes(ev) -> None:  # in the run's own task: cancelled at its next wait, the closing stop
            engine = svc._engine
            if isinstance(ev, StatusEvent) and ev.state == "stopping" and not cancelled and engine is not None:
                assert svc._run_task is not None
                cancelled.append(ev.message)
                svc._run_task.cancel()

        try:
            await wait(rc.status, "idle")
            mark = rc.watch.mark()
            assert (await wait(rc.command, {"cmd": "start", "matrix": "quick"}))["ok"] is True
            run_id = (await wait(rc.status, "running"))["run_id"]
            assert svc._engine is not None
            svc._engine.subscribe(cancel_as_it_closes)
            ended = await wait(rc.status, lambda s: s["state"] == "idle" and s.get("run_id") == run_id, 60, mark)
        finally:
            rc.close()
            shutdown.set()
            await asyncio.wait_for(asyncio.gather(serving, return_exceptions=True), 120)
    assert cancelled == ["all points completed"], cancelled  # no stop nor abort asked: the plan's own end
    said = "all points completed; run cancelled while stopping"
    assert ended["message"].startswith(f"run aborted: {said}"), ended["message"]
    assert "(all points completed)" not in ended["message"] and "incomplete" not in ended["message"], ended
    (run_dir,) = [p.parent for p in (tmp_path / "runs").glob("*/run.h5")]
    stored = read_run(run_dir)
    assert (str(stored.status), stored.status_message) == ("aborted", said)
    assert f"ended: aborted: {said}\n" in (run_dir / "run.log").read_text()
