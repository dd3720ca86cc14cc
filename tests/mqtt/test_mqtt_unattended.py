"""Without the broker nobody can answer the run: once supervision is lost, a pause or a
confirmation the run waits for stops it after [interlocks] unanswered_pause_s, whatever
the supervision policy, and both drives come to a standstill. In process: the service
the CLI builds, on the simulator, with a real mosquitto that is stopped."""

from __future__ import annotations

import asyncio
import json
from pathlib import Path

import pytest

from support.mqtt_helpers import Broker, RigClient, unsupervised_service, wait
from orbitrig.config import load_rig

UNANSWERED_S = 2.0  # [interlocks] unanswered_pause_s, short here (60 s by default)


def rig_with_short_unanswered_wait():
    rig = load_rig()
    interlocks = rig.interlocks.model_copy(update={"unanswered_pause_s": UNANSWERED_S})
    return rig.model_copy(update={"interlocks": interlocks})


@pytest.mark.parametrize(
    "policy, confirm, unsupervised",
    [
        ("pause", "auto", "paused"),  # running when the broker goes: paused by the policy, nobody resumes
        ("keep", "remote", "waiting"),  # waiting for a confirmation when the broker goes: nobody confirms
    ],
)
async def test_an_unanswered_wait_without_the_broker_stops_the_run(policy, confirm, unsupervised, tmp_path: Path):
    from sim.rig import SimRig

    b = Broker(tmp_path / "broker")
    b.start()
    rc = None
    try:
        async with SimRig(speedup=20, adc_pty=False) as sim_rig:
            rig = rig_with_short_unanswered_wait()
            service = unsupervised_service(b, tmp_path, "un", policy, sim_rig, rig=rig, confirm=confirm)
            stop = asyncio.Event()
            serving = asyncio.create_task(service.serve(stop))
            try:
                rc = RigClient(b, "un")
                await wait(rc.status, "idle")
                assert (await wait(rc.command, {"cmd": "start", "matrix": "long"}))["ok"] is True
                await wait(rc.status, "running" if confirm == "auto" else "waiting")
                await asyncio.sleep(0.3)
                rc.close()
                rc = None
                b.stop()
                states = []
                for _ in range(300):  # supervision lost after 1 s, the run stopped 2 s into the wait
                    await asyncio.sleep(0.1)
                    states.append(service.state)
                    if not service.run_active:
                        break
                assert unsupervised in states, states
                assert not service.run_active and service.state == "idle", states
                assert json.loads(service._status)["message"].startswith("run stopped"), service._status
                for _ in range(50):  # the run's cleanup waited for standstill; the drives stay there
                    assert all(abs(w) < 1e-3 for w in sim_rig.speeds), sim_rig.speeds
                    await asyncio.sleep(0.02)
                log = next((tmp_path / "runs").glob("*/run.log")).read_text()
                assert "nobody can answer" in log, log[-2000:]
            finally:
                stop.set()
                service.abort_run("test over")
                await asyncio.wait_for(asyncio.gather(serving, return_exceptions=True), 60)
    finally:
        if rc is not None:
            rc.close()
        b.stop()
