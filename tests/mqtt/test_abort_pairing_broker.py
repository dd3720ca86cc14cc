"""The same abort sent again after the abort connection missed the first one, end to end:
a real mosquitto, the rig service in process with both its connections (the main one and
the abort connection) through relays the test can cut or hold.

The abort connection is down while abort #1 is published: only the main connection gets
it. Once the abort connection is back, the main connection is held (a flood ahead of
everything on it) and the operator publishes the same bytes again: #2 is carried out and
answered off the abort connection at once, not taken for the second copy of #1; its main
copy, read once the hold ends, is dropped. Two aborts, two replies."""

from __future__ import annotations

import asyncio
import dataclasses
import json
import socket
import threading
import time
from pathlib import Path

from orbitrig.service.rig_service import BrokerSettings, RigService, ServiceSettings
from orbitrig.service.settings import AbortAccount
from support.mqtt_helpers import ACCOUNTS, Broker, CutProxy, Watcher
from support.polling import until

RIG = "pairing-rig"
ABORT = json.dumps({"cmd": "abort", "id": "estop"})  # a button bridge's fixed id: the same bytes each time


class HoldingRelay(CutProxy):
    """A TCP relay to the broker: ``hold`` stops passing what the broker sends (kept, in
    order, until ``release``); ``cut`` closes every relayed connection and refuses new
    ones until ``restore``."""

    def __init__(self, target: int):
        self.held = False
        super().__init__(target)

    def _relay(self, client: socket.socket, broker: socket.socket) -> None:
        threading.Thread(target=self._pass, args=(client, broker, False), daemon=True).start()
        threading.Thread(target=self._pass, args=(broker, client, True), daemon=True).start()

    def _pass(self, src: socket.socket, dst: socket.socket, from_broker: bool) -> None:
        try:
            while data := src.recv(65536):
                while from_broker and self.held and self.open:
                    time.sleep(0.01)
                dst.sendall(data)
        except OSError:
            pass

    def hold(self) -> None:
        self.held = True

    def release(self) -> None:
        self.held = False

    def restore(self) -> None:
        self.open, self.held = True, False


async def test_the_same_abort_sent_again_after_one_the_abort_connection_missed(broker: Broker, tmp_path: Path):
    main, side = HoldingRelay(broker.port), HoldingRelay(broker.port)
    settings = ServiceSettings(rig_id=RIG, matrices_dir=tmp_path, reconnect_initial=0.2, reconnect_max=0.5)
    account = AbortAccount("orbitrig-service-abort", ACCOUNTS["orbitrig-service-abort"])
    creds = BrokerSettings.from_url(
        f"mqtt://127.0.0.1:{main.port}",
        username="orbitrig-service",
        password=ACCOUNTS["orbitrig-service"],
        abort=account,
    )
    service = RigService(settings, creds, engine_factory=None, load_matrix=None)
    assert service.abort_link is not None
    service.abort_link.broker = dataclasses.replace(service.abort_link.broker, port=side.port)
    stop = asyncio.Event()
    serving = asyncio.create_task(service.serve(stop))
    watch = Watcher(broker, f"orbitrig/{RIG}/reply")

    def replies() -> list[dict]:
        return [m.json() for m in watch.messages]

    async def publish_abort() -> None:
        done = await asyncio.to_thread(broker.pub, f"orbitrig/{RIG}/abort", ABORT)
        assert done.returncode == 0, done.stderr

    try:
        link, abort_link = service.link, service.abort_link
        await until(lambda: link.online.is_set() and abort_link.up, 30, "both connections up")
        side.cut()  # the abort connection drops; it reconnects with backoff
        await until(lambda: not abort_link.up, 30, "the abort connection down")
        await publish_abort()  # #1: the main connection only
        await until(lambda: len(replies()) == 1, 30, "abort #1 answered (off the main connection)")
        side.restore()
        await until(lambda: abort_link.up and abort_link.connections >= 2, 30, "the abort connection back")
        await asyncio.sleep(1.0)  # (its subscription well established)
        main.hold()  # the main connection behind a flood: its copies wait
        await publish_abort()  # #2, the same bytes
        await until(
            lambda: len(replies()) == 2, 15, "abort #2 answered off the abort connection while the main one waits"
        )
        main.release()  # the main connection's copy of #2 comes in
        counts = service.triage.counts
        await until(lambda: counts["at once"] + counts["second copy"] >= 3, 30, "#2's main copy read")
        assert [r["id"] for r in replies()] == ["estop", "estop"], replies()
        assert service.triage.counts["at once"] == 2, service.triage.counts
        assert service.triage.counts["second copy"] == 1, service.triage.counts  # #2's main copy
    finally:
        main.release()
        watch.close()
        stop.set()
        await asyncio.wait_for(serving, 30)
        main.close()
        side.close()
