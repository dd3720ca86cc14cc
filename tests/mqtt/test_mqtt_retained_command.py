"""A command left retained on <prefix>/cmd (spec: cmd is not retained) is stale: the broker
replays it on every subscription. The service refuses it with one reply and changes
nothing; a live command right after is executed as usual. A retained stop or abort is
accepted and carried out all the same (spec: stop and abort are always accepted; an abort
to a service built without a drive link is answered "not sent"). Real
mosquitto, real clients."""

from __future__ import annotations

import asyncio
import json
from pathlib import Path

from support.mqtt_helpers import ACCOUNTS, RigClient, write_matrices
from orbitrig.config import load_matrix
from orbitrig.service.rig_service import BrokerSettings, RigService, ServiceSettings


class StartRecorder:
    """An engine factory that records the matrix of each start it is asked for and starts no run."""

    def __init__(self) -> None:
        self.started: list[str] = []

    def __call__(self, name, matrix):
        self.started.append(name)
        raise RuntimeError("engine not available in this test")


def _service(broker, rig_id: str, matrices: Path, factory) -> RigService:
    """The service of ``rig_id`` on the broker as the shipped service account, on ``matrices``."""
    return RigService(
        ServiceSettings(rig_id=rig_id, matrices_dir=matrices),
        BrokerSettings.from_url(broker.url, username="orbitrig-service", password=ACCOUNTS["orbitrig-service"]),
        engine_factory=factory,
        load_matrix=load_matrix,
    )


async def test_retained_start_is_refused_and_starts_nothing(broker, tmp_path: Path):
    rig_id = "retained1"
    topic = f"orbitrig/{rig_id}/cmd"
    factory = StartRecorder()
    started = factory.started

    done = await asyncio.to_thread(
        broker.pub, topic, json.dumps({"cmd": "start", "id": "stale", "matrix": "quick"}), retain=True
    )
    assert done.returncode == 0, done.stderr
    rc = RigClient(broker, rig_id)
    service = _service(broker, rig_id, write_matrices(tmp_path / "matrices"), factory)
    stop = asyncio.Event()
    task = asyncio.create_task(service.serve(stop))
    try:
        reply = await asyncio.to_thread(rc.reply, "stale", 10.0)
        assert reply["ok"] is False and "retained command 'start' refused" in reply["error"]
        assert started == [] and not service.run_active and service.state == "idle"
        # a live (not retained) start of the same matrix reaches the engine factory
        live = await asyncio.to_thread(rc.command, {"cmd": "start", "matrix": "quick"})
        assert live["ok"] is False and "engine not available" in live["error"] and started == ["quick"]
        replies = [m for m in rc.watch.on("reply") if m.json().get("id") == "stale"]
        assert len(replies) == 1  # exactly one reply to the stale command
    finally:
        await asyncio.to_thread(broker.pub, topic, b"", retain=True)  # clear the retained command
        rc.close()
        stop.set()
        await asyncio.wait_for(task, 10)


async def test_retained_stop_and_abort_are_accepted(broker, tmp_path: Path):
    rig_id = "retained2"
    topic = f"orbitrig/{rig_id}/cmd"
    rc = RigClient(broker, rig_id)
    service = _service(broker, rig_id, write_matrices(tmp_path / "matrices"), lambda name, matrix: None)  # no run
    stop = asyncio.Event()
    task = None
    try:
        for cmd in ("stop", "abort"):
            await asyncio.to_thread(broker.pub, topic, json.dumps({"cmd": cmd, "id": f"kept-{cmd}"}), retain=True)
            task = asyncio.create_task(service.serve(stop))
            reply = await asyncio.to_thread(rc.reply, f"kept-{cmd}", 10.0)
            # carried out: no run holds the drives and no drive link is known: nothing sent, said so
            assert reply["ok"] is False and reply["error"].startswith("not sent: no run holds"), reply
            stop.set()
            await asyncio.wait_for(task, 10)
            stop.clear()
    finally:
        await asyncio.to_thread(broker.pub, topic, b"", retain=True)
        rc.close()
        stop.set()
        if task is not None and not task.done():
            await asyncio.wait_for(task, 10)


async def test_a_command_published_retained_to_a_listening_service_is_carried_out(broker, tmp_path: Path):
    """Only the copy the broker replays as the service subscribes carries the retain flag: a
    command published with it while the service listens comes as a live one and is carried out;
    the same message handed over at the service's next start is refused."""
    rig_id = "retained3"
    topic = f"orbitrig/{rig_id}/cmd"
    factory = StartRecorder()
    started = factory.started

    rc = RigClient(broker, rig_id)
    matrices = write_matrices(tmp_path / "matrices")

    def service() -> RigService:
        return _service(broker, rig_id, matrices, factory)

    stop = asyncio.Event()
    task = asyncio.create_task(service().serve(stop))
    try:
        await asyncio.to_thread(rc.status, "idle")
        assert "ok" in await asyncio.to_thread(rc.command, {"cmd": "confirm"})  # answered: the service listens
        mark = rc.watch.mark()
        message = json.dumps({"cmd": "start", "id": "kept", "matrix": "quick"})
        assert (await asyncio.to_thread(broker.pub, topic, message, retain=True)).returncode == 0
        live = await asyncio.to_thread(rc.reply, "kept", 10.0, mark)
        assert live["ok"] is False and "engine not available" in live["error"] and started == ["quick"]
        stop.set()
        await asyncio.wait_for(task, 10)
        stop.clear()
        mark = rc.watch.mark()
        task = asyncio.create_task(service().serve(stop))  # subscribes again: the broker replays the message
        replayed = await asyncio.to_thread(rc.reply, "kept", 10.0, mark)
        assert replayed["ok"] is False and "retained command 'start' refused" in replayed["error"]
        assert started == ["quick"]
    finally:
        await asyncio.to_thread(broker.pub, topic, b"", retain=True)
        rc.close()
        stop.set()
        await asyncio.wait_for(task, 10)
