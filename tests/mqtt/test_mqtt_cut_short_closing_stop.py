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
