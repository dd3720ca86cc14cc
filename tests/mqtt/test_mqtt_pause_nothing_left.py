"""An MQTT `pause` once every point is measured: from the last point's identification on (past
its last safe point) and in the closing ramp no safe point is left, so no pause could hold the run.
The service refuses it (`ok: false`) with the run's own words, why and what happens instead (the
run completes), the rule the terminal's Ctrl-C follows (orbitrig.run.control.NothingToPause); the
refused pause is not recorded and the run completes. Before, it was accepted with 'the run pauses
at its next safe point', and the run completed without ever pausing.

Real parts: mosquitto with the shipped ACL and accounts, the service `orbitrig serve --sim` builds
(in process, on the simulator, over Modbus TCP), run.log and run.h5. The pause is sent as the real
step starts (its identification, or the closing ramp's stop), the step going on once it is answered."""

from __future__ import annotations

import asyncio

import pytest

from orbitrig.run.control import CLOSING_RAMP, NOTHING_TO_PAUSE
from orbitrig.run.point_record import PointRecord
from orbitrig.run.procedure import PointProcedure
from support.mqtt_helpers import RigClient, service_in_process, wait

pytestmark = pytest.mark.timeout(120)


def _pause_as_it_starts(monkeypatch, where: str, rc_of, replies: list[dict], said: list[str]) -> None:
    """The MQTT pause sent, and answered, as the step `where` starts (the last point's identification,
    or the closing ramp's stop, no point left), what the run said then kept; the step then runs."""
    cls, name = (PointRecord, "identify") if where == "identification" else (PointProcedure, "stop_drives")
    step_of = getattr(cls, name)

    async def paused_first(self, step, ps):
        if where == "identification" or ps is None:  # (the one point is the last; the closing ramp's stop)
            if ps is None:  # what the operator sees as the pause is sent: the closing ramp's status
                said.append((await wait(rc_of().status, lambda s: s["message"] == CLOSING_RAMP, 10))["state"])
            replies.append(await wait(rc_of().command, {"cmd": "pause", "by": "ada"}))
        await step_of(self, step, ps)

    monkeypatch.setattr(cls, name, paused_first)


@pytest.mark.parametrize("where", ["identification", "closing ramp"])
async def test_a_pause_with_no_safe_point_left_is_refused_saying_why(broker, tmp_path, monkeypatch, where):
    from orbitrig.store.reader import read_run
    from sim.rig import SimRig

    replies: list[dict] = []
    said: list[str] = []
    clients: list[RigClient] = []
    _pause_as_it_starts(monkeypatch, where, lambda: clients[0], replies, said)
    async with SimRig(speedup=40.0, adc_pty=False) as sim_rig:
        svc = service_in_process(broker.url, tmp_path, "no-pause-rig", sim_rig=sim_rig, reconnect_initial=0.2)
        shutdown = asyncio.Event()
        serving = asyncio.create_task(svc.serve(shutdown))
        rc = RigClient(broker, "no-pause-rig")
        clients.append(rc)
        try:
            await wait(rc.status, "idle")
            mark = rc.watch.mark()
            assert (await wait(rc.command, {"cmd": "start", "matrix": "quick"}))["ok"] is True
            run_id = (await wait(rc.status, "running"))["run_id"]
            ended = await wait(rc.status, lambda s: s["state"] == "idle" and s.get("run_id") == run_id, 60, mark)
            states = [m.json()["state"] for m in rc.watch.on("status", mark)]
        finally:
            rc.close()
            shutdown.set()
            await asyncio.wait_for(asyncio.gather(serving, return_exceptions=True), 120)
    assert [(r["ok"], r.get("error")) for r in replies] == [(False, NOTHING_TO_PAUSE)], replies
    assert said == (["running"] if where == "closing ramp" else []), said
    assert "paused" not in states, states
    assert ended["message"] == "run completed", ended
    (run_dir,) = [p.parent for p in (tmp_path / "runs").glob("*/run.h5")]
    log = (run_dir / "run.log").read_text()
    assert "pause" not in log, log  # refused: not recorded, neither asked nor reached
    stored = read_run(run_dir)
    assert (str(stored.status), stored.status_message) == ("completed", "all points completed")
