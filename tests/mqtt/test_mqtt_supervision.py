"""A long loss of supervision (no broker) during a run: the configured policy
(pause or stop) is applied once, the run goes on otherwise, and the status is
republished when the broker is back. In process: the service the CLI builds,
on the simulator, with a real mosquitto that is stopped and started."""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest

from support.mqtt_helpers import Broker, RigClient, retained, unsupervised_service, wait


@pytest.mark.parametrize("policy, expected", [("pause", "paused"), ("stop", "idle")])
async def test_supervision_policy(policy, expected, tmp_path: Path):
    from sim.rig import SimRig

    b = Broker(tmp_path / "broker")
    b.start()
    rc = None
    try:
        async with SimRig(speedup=20, adc_pty=False) as sim_rig:
            service = unsupervised_service(b, tmp_path, "sup", policy, sim_rig)
            stop = asyncio.Event()
            serving = asyncio.create_task(service.serve(stop))
            try:
                rc = RigClient(b, "sup")
                await wait(rc.status, "idle")
                assert (await wait(rc.command, {"cmd": "start", "matrix": "long"}))["ok"] is True
                run_id = (await wait(rc.status, "running"))["run_id"]
                rc.close()
                b.stop()
                # the run goes on without the broker until the policy applies (after 1 s)
                for _ in range(100):
                    await asyncio.sleep(0.1)
                    if service.state == expected:
                        break
                assert service.state == expected, service.state
                assert service.run_active is (policy == "pause")
                b.start()
                rc = RigClient(b, "sup")
                st = await wait(rc.status, lambda s: s["run_id"] == run_id, 20)  # republished
                assert st["state"] == expected
                assert (await wait(retained, b, "orbitrig/sup/status")).json()["state"] == expected
                if policy == "pause":  # an operator takes over again
                    assert (await wait(rc.command, {"cmd": "resume"}))["ok"] is True
                    await wait(rc.status, "running")
                    assert (await wait(rc.command, {"cmd": "abort"}))["ok"] is True
                    await wait(rc.status, "idle")
            finally:
                stop.set()
                await asyncio.wait_for(serving, 60)
    finally:
        if rc is not None:
            rc.close()
        b.stop()
