"""Commands and replies across a lost link, against a real mosquitto (shipped ACL and
accounts) and a relay that reads the MQTT packets each way, holds them and cuts the link:

- every command the service took in (and so acknowledged: the broker never sends it again)
  before its link dropped is carried out and answered once, on the next connection;
- the broker's redelivery of a command whose acknowledgement was lost with the link is
  carried out once; the same command sent again by an operator after the reconnection is a
  new command: carried out and answered (not dropped in silence);
- a reply the broker acknowledged to the service is never published again after a
  reconnection (one it did not acknowledge may be: QoS 1 is at least once).
"""

from __future__ import annotations

import asyncio
import collections
import json
import logging
import re
import socket
import threading
from collections.abc import Callable
from pathlib import Path

import pytest

from orbitrig.service import inbox
from orbitrig.service.rig_service import BrokerSettings, RigService, ServiceSettings
from support.mqtt_helpers import ACCOUNTS, CutProxy, Watcher, serving
from support.polling import until

#: replies the broker acknowledges to the service before the link drops (of 50, sent in two batches)
ACKED = 20


def _every(packet: bytes) -> bool:
    return True


class PacketRelay(CutProxy):
    """127.0.0.1:port -> the broker, one MQTT packet at a time each way (``up``: service ->
    broker). ``held_if[up](packet)`` True: that packet is held (the others go on) until
    ``held_if[up]`` is None again, then the held ones go first; ``watch[up](packet)`` sees each
    packet as it comes and may return True to hold every later one of that direction.
    ``cut()`` drops every connection with what it held (and the watches) and refuses new ones
    until ``restore()``."""

    def __init__(self, target: int):
        self.held_if: dict[bool, Callable[[bytes], bool] | None] = {True: None, False: None}
        self.watch: dict[bool, Callable[[bytes], bool]] = {True: lambda p: False, False: lambda p: False}
        super().__init__(target)

    def _relay(self, client: socket.socket, broker: socket.socket) -> None:
        threading.Thread(target=self._pump_packets, args=(client, broker, True), daemon=True).start()
        threading.Thread(target=self._pump_packets, args=(broker, client, False), daemon=True).start()

    def _pump_packets(self, src: socket.socket, dst: socket.socket, up: bool) -> None:
        buf, held = b"", []
        src.settimeout(0.02)
        try:
            while True:
                try:
                    data = src.recv(65536)
                    if not data:
                        return
                    buf += data
                except TimeoutError:
                    pass
                while (n := _packet_length(buf)) is not None:
                    packet, buf = buf[:n], buf[n:]
                    hold_later = self.watch[up](packet)
                    held_if = self.held_if[up]
                    if held_if is not None and held_if(packet):
                        held.append(packet)
                    else:
                        if held_if is None and held:
                            dst.sendall(b"".join(held))
                            held = []
                        dst.sendall(packet)
                    if hold_later:
                        self.held_if[up] = _every
                if self.held_if[up] is None and held:
                    dst.sendall(b"".join(held))
                    held = []
        except OSError:
            return

    def cut(self) -> None:
        super().cut()
        self.held_if = {True: None, False: None}
        self.watch = {True: lambda p: False, False: lambda p: False}


def _varint(data: bytes, at: int) -> tuple[int, int] | None:
    """(value, bytes used) of the MQTT variable byte integer at ``at``; None if incomplete."""
    value, shift = 0, 0
    for i in range(at, min(at + 4, len(data))):
        value |= (data[i] & 0x7F) << shift
        shift += 7
        if not data[i] & 0x80:
            return value, i + 1 - at
    return None


def _packet_length(buf: bytes) -> int | None:
    """Length of the complete MQTT packet at the start of ``buf``, None if it is not all there."""
    if len(buf) < 2 or (rl := _varint(buf, 1)) is None:
        return None
    n = 1 + rl[1] + rl[0]
    return n if len(buf) >= n else None


def _publish(packet: bytes) -> tuple[str, int | None, bytes] | None:
    """(topic, packet id, payload) of an MQTT 5 PUBLISH, else None."""
    if packet[0] >> 4 != 3:
        return None
    at = 1 + _varint(packet, 1)[1]
    end = at + 2 + int.from_bytes(packet[at : at + 2], "big")
    topic = packet[at + 2 : end].decode()
    pid = None
    if (packet[0] >> 1) & 3:
        pid, end = int.from_bytes(packet[end : end + 2], "big"), end + 2
    length, used = _varint(packet, end)
    return topic, pid, packet[end + used + length :]


def _puback_id(packet: bytes) -> int | None:
    if packet[0] >> 4 != 4:
        return None
    at = 1 + _varint(packet, 1)[1]
    return int.from_bytes(packet[at : at + 2], "big")


def _service(broker_url: str, tmp_path: Path, rig: str) -> RigService:
    settings = ServiceSettings(rig_id=rig, matrices_dir=tmp_path, reconnect_initial=0.2, reconnect_max=0.5)
    creds = BrokerSettings.from_url(broker_url, username="orbitrig-service", password=ACCOUNTS["orbitrig-service"])
    return RigService(settings, creds, engine_factory=None, load_matrix=None)


class Executed(logging.Handler):
    """id -> how often the service carried a command out (its log line ``command <cmd> (id '<id>')``)."""

    def __init__(self) -> None:
        super().__init__(logging.INFO)
        self.counts: collections.Counter[str] = collections.Counter()

    def emit(self, record: logging.LogRecord) -> None:
        if found := re.fullmatch(r"command \w+ \(id '(.*)'\)", record.getMessage()):
            self.counts[found[1]] += 1


@pytest.fixture
def executed():
    logger = logging.getLogger("orbitrig.service.rig_service")
    handler, level = Executed(), logger.level
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    yield handler.counts
    logger.removeHandler(handler)
    logger.setLevel(level)


async def _reconnect(service: RigService, relay: PacketRelay) -> None:
    before = service.link.connections
    relay.cut()
    await until(lambda: not service.link.online.is_set(), 30, "the service sees its link drop")
    relay.restore()
    await until(lambda: service.link.connections > before and service.link.online.is_set(), 60, "reconnected")


def _checked(service: RigService) -> bool:
    """The connection's end-to-end check is done (its own status came back): nothing it sends
    is held before (a link without that check: nothing to wait for)."""
    delivery = getattr(service.link, "delivery", None)
    return delivery is None or delivery.verified


def _replies(watch: Watcher) -> collections.Counter[str]:
    return collections.Counter(m.json()["id"] for m in list(watch.messages))


async def test_commands_taken_in_before_the_link_dropped_are_carried_out_once(broker, tmp_path, monkeypatch, executed):
    monkeypatch.setattr(inbox, "COMMAND_RATE", 20.0)  # slow: commands wait in the service when the link drops
    relay = PacketRelay(broker.port)
    service = _service(relay.url, tmp_path, "carry-rig")
    watch = Watcher(broker, "orbitrig/carry-rig/reply")
    ids = [f"q{i}" for i in range(60)]
    try:
        async with serving(service):
            for cid in ids:  # QoS 1, as fast as the operator can: read (and acknowledged) at once
                done = await asyncio.to_thread(
                    broker.pub, "orbitrig/carry-rig/cmd", json.dumps({"cmd": "pause", "id": cid})
                )
                assert done.returncode == 0, done.stderr
            await until(lambda: sum(executed.values()) >= 5, 30, "the first commands carried out")
            assert sum(executed.values()) < len(ids), "all carried out before the cut: nothing tested"
            await _reconnect(service, relay)
            await until(lambda: set(_replies(watch)) >= set(ids), 60, f"every command answered: {_replies(watch)}")
            await asyncio.sleep(1.0)
        assert all(executed[cid] == 1 for cid in ids), executed
    finally:
        watch.close()
        relay.close()


async def test_a_redelivery_runs_once_and_the_same_command_sent_again_is_answered(broker, tmp_path, executed, caplog):
    caplog.set_level(logging.INFO, logger="orbitrig.service.link")
    relay = PacketRelay(broker.port)
    service = _service(relay.url, tmp_path, "again-rig")
    watch = Watcher(broker, "orbitrig/again-rig/reply")
    command = json.dumps({"cmd": "pause", "id": "r1"})
    try:
        async with serving(service):
            await until(lambda: _checked(service), 30, "the connection's end-to-end check done")
            relay.held_if[True] = _every  # nothing the service sends reaches the broker: its PUBACK, its reply
            assert (await asyncio.to_thread(broker.pub, "orbitrig/again-rig/cmd", command)).returncode == 0
            await until(lambda: executed["r1"] == 1, 30, "the command carried out")
            await _reconnect(service, relay)  # the broker redelivers it (DUP): its acknowledgement was lost
            await until(lambda: _replies(watch)["r1"] == 1, 30, "the reply sent again on the new connection")
            await asyncio.sleep(2.0)
            assert executed["r1"] == 1 and _replies(watch)["r1"] == 1, (executed, _replies(watch))

            # the operator sends the very same command again (e.g. from the shell's history): a new one
            assert (await asyncio.to_thread(broker.pub, "orbitrig/again-rig/cmd", command)).returncode == 0
            await until(lambda: _replies(watch)["r1"] == 2, 15, f"the repeated command answered: {_replies(watch)}")
            assert executed["r1"] == 2
        assert "dropped the broker's redelivery of command" in caplog.text  # (it came, DUP set, packet id kept)
    finally:
        watch.close()
        relay.close()


async def test_a_reply_the_broker_acknowledged_is_not_sent_again(broker, tmp_path, executed):
    relay = PacketRelay(broker.port)
    service = _service(relay.url, tmp_path, "acked-rig")
    watch = Watcher(broker, "orbitrig/acked-rig/reply")
    ids = [f"p{i}" for i in range(50)]
    reply_of: dict[int, str] = {}  # packet id of the service's PUBLISH on reply -> the reply's id
    acked: list[str] = []  # replies whose PUBACK the relay passed on to the service

    def up(packet: bytes) -> bool:
        publish = _publish(packet)
        if publish is not None and publish[0] == "orbitrig/acked-rig/reply" and publish[1] is not None:
            reply_of[publish[1]] = json.loads(publish[2])["id"]
        return False

    def a_reply(packet: bytes) -> bool:
        publish = _publish(packet)
        return publish is not None and publish[0] == "orbitrig/acked-rig/reply"

    def down(packet: bytes) -> bool:
        pid = _puback_id(packet)
        if pid is not None and pid in reply_of and len(acked) < ACKED:  # (later ones are held)
            acked.append(reply_of.pop(pid))
            return len(acked) >= ACKED  # the broker -> service direction held after this one
        return False

    try:
        async with serving(service):
            await until(lambda: _checked(service), 30, "the connection's end-to-end check done")
            relay.watch[True] = up
            relay.held_if[True] = a_reply  # the replies pile up in the service (commands are acknowledged)
            for cid in ids:
                done = await asyncio.to_thread(
                    broker.pub, "orbitrig/acked-rig/cmd", json.dumps({"cmd": "pause", "id": cid})
                )
                assert done.returncode == 0, done.stderr
            await until(lambda: sum(executed.values()) == len(ids), 30, "every command carried out")
            relay.watch[False] = down
            relay.held_if[True] = None  # a first batch goes, then the rest: ACKED acknowledged to the service
            await until(lambda: relay.held_if[False] is not None, 30, f"{ACKED} replies acknowledged")
            assert len(acked) == ACKED
            await asyncio.sleep(0.5)  # the service reads those acknowledgements
            await _reconnect(service, relay)
            await until(lambda: set(_replies(watch)) >= set(ids), 30, f"every command answered: {_replies(watch)}")
            await asyncio.sleep(2.0)
        replies = _replies(watch)
        again = {cid: replies[cid] for cid in acked if replies[cid] != 1}
        assert not again, f"acknowledged by the broker, published again: {again} (acknowledged: {acked})"
        assert all(executed[cid] == 1 for cid in ids), executed
    finally:
        watch.close()
        relay.close()
