"""Stop and abort payloads end to end: a real mosquitto, operators publishing with
mosquitto_pub, the rig service in process with its abort connection (no run, so a stop is
answered ok and an abort "not sent: no run holds the drives ...": either way carried out,
not refused for its payload).

- a stop over 4096 bytes, one nested 40 levels deep, and an abort whose "cmd" is given
  twice with the same value are carried out;
- an abort whose id is longer than 128 characters is carried out and answered with id
  null, never with the id cut short; another command with such an id is refused, id null;
- on the abort topic, plain text and truncated JSON are answered with the reason they
  cannot be read; an empty (retained-clearing) message gets no reply, there nor on cmd;
- "ABORT", " Stop " and a payload behind a UTF-8 byte order mark are carried out."""

from __future__ import annotations

import asyncio
import json
import subprocess
import time
from pathlib import Path

import pytest

from orbitrig.service.rig_service import BrokerSettings, RigService, ServiceSettings
from orbitrig.service.settings import AbortAccount
from support.mqtt_helpers import ACCOUNTS, Broker, Watcher

RIG = "payloads-rig"
PREFIX = f"orbitrig/{RIG}"
NOT_SENT = "not sent: no run holds the drives"


@pytest.fixture
async def service(broker: Broker, tmp_path: Path):
    settings = ServiceSettings(rig_id=RIG, matrices_dir=tmp_path)
    account = AbortAccount("orbitrig-service-abort", ACCOUNTS["orbitrig-service-abort"])
    creds = BrokerSettings.from_url(
        broker.url, username="orbitrig-service", password=ACCOUNTS["orbitrig-service"], abort=account
    )
    svc = RigService(settings, creds, engine_factory=None, load_matrix=None)
    stop = asyncio.Event()
    serving = asyncio.create_task(svc.serve(stop))
    try:
        deadline = time.monotonic() + 30
        while not (svc.link.online.is_set() and svc.abort_link is not None and svc.abort_link.up):
            assert time.monotonic() < deadline, "the service's connections are not up"
            await asyncio.sleep(0.05)
        yield svc
    finally:
        stop.set()
        await asyncio.wait_for(serving, 30)


def publish(broker: Broker, topic: str, payload: bytes, retain: bool) -> subprocess.CompletedProcess:
    if payload:
        return broker.pub(topic, payload, retain=retain)
    flags = ["-n", "-r"] if retain else ["-n"]  # an empty message (mosquitto_pub -s refuses empty input)
    args = ["mosquitto_pub", *broker.client_args("operator"), "-q", "1", "-t", topic, *flags]
    return subprocess.run(args, capture_output=True, timeout=10)


async def replies_to(broker: Broker, sends: list[tuple[str, bytes, bool]], settle: float = 2.0) -> list[dict]:
    """Publish each (topic, payload, retain) as the operator; every reply seen until
    ``settle`` s after the last."""
    watch = Watcher(broker, f"{PREFIX}/reply")
    try:
        for topic, payload, retain in sends:
            done = await asyncio.to_thread(publish, broker, f"{PREFIX}/{topic}", payload, retain)
            assert done.returncode == 0, done.stderr
        await asyncio.sleep(settle)
        return [m.json() for m in watch.messages]
    finally:
        watch.close()


async def test_stop_and_abort_beyond_the_limits_are_carried_out(broker, service):
    big_stop = json.dumps({"cmd": "stop", "id": "big-stop", "note": "x" * 5000}).encode()
    deep_stop = b'{"cmd":"stop","id":"deep-stop","n":' + b"[" * 40 + b"]" * 40 + b"}"
    twice = b'{"cmd":"abort","cmd":"abort","id":"twice-abort"}'
    replies = await replies_to(
        broker, [("cmd", big_stop, False), ("cmd", deep_stop, False), ("cmd", twice, False), ("abort", big_stop, False)]
    )
    by_id: dict[str, list[dict]] = {}
    for reply in replies:
        by_id.setdefault(reply["id"], []).append(reply)
    # carried out: no run and no drive link known, so nothing could be sent, and each reply says so
    assert [r["error"][: len(NOT_SENT)] for r in by_id["big-stop"]] == [NOT_SENT] * 2, replies  # on cmd and abort
    assert [r["error"][: len(NOT_SENT)] for r in by_id["deep-stop"]] == [NOT_SENT], replies
    assert len(by_id["twice-abort"]) == 1 and by_id["twice-abort"][0]["error"].startswith(NOT_SENT), replies
    assert service.triage.counts["at once"] == 4, service.triage.counts


async def test_an_id_too_long_is_never_echoed_cut_short(broker, service):
    long_id = "i" * 200
    abort = json.dumps({"cmd": "abort", "id": long_id}).encode()
    status = json.dumps({"cmd": "status", "id": long_id}).encode()
    replies = await replies_to(broker, [("cmd", abort, False), ("cmd", status, False)])
    assert all(r["id"] is None for r in replies), replies  # neither the id nor its first 128 characters
    assert len(replies) == 2, replies
    (carried,) = [r for r in replies if r["ok"] is False and r["error"].startswith(NOT_SENT)]  # carried out
    assert "id sent is not echoed: it has 200 characters (at most 128)" in carried["error"], carried  # why null
    assert any(r["ok"] is False and r["error"].startswith("field 'id'") for r in replies), replies


async def test_the_abort_topic_says_why_and_an_empty_message_is_not_answered(broker, service):
    replies = await replies_to(
        broker,
        [
            ("abort", b"abort", False),
            ("abort", b'{"cmd":"abort","id":"cut-short"', False),
            ("abort", b"", True),  # clearing a retained message, as the docs tell operators
            ("cmd", b"", True),
        ],
    )
    errors = [r["error"] for r in replies]
    assert len(replies) == 2 and all(r["id"] is None for r in replies), replies  # once each, the empty ones not
    assert errors[0].startswith("payload is not JSON: Expecting value at line 1 column 1"), errors
    assert errors[1].startswith("payload is not JSON: Expecting ',' delimiter"), errors
    assert service.triage.counts["at once"] == 0


async def test_a_stop_or_abort_spelled_otherwise_or_with_a_bom_is_carried_out(broker, service, caplog):
    """ "ABORT", " Stop " and a UTF-8 byte order mark (some tools write one) on either topic:
    carried out at once, the spelling said in the service's log; "START" is still refused."""
    sends = [
        ("abort", b'{"cmd":"ABORT","id":"upper-abort"}', False),
        ("cmd", b'{"cmd":" Stop ","id":"blank-stop"}', False),
        ("abort", b'\xef\xbb\xbf{"cmd":"abort","id":"bom-abort"}', False),
        ("cmd", b'{"cmd":"START","id":"upper-start","matrix":"demo"}', False),
    ]
    replies = {r["id"]: r for r in await replies_to(broker, sends)}
    for cid in ("upper-abort", "blank-stop", "bom-abort"):
        assert replies[cid]["error"].startswith(NOT_SENT), replies  # carried out (no run: nothing to stop)
    said = [r.getMessage() for r in caplog.records if "accepted despite" in r.getMessage()]
    assert any("'ABORT' read as 'abort'" in m for m in said), said
    assert any("' Stop ' read as 'stop'" in m for m in said), said
    assert replies["upper-start"]["error"].startswith("unknown command 'START'"), replies
    assert service.triage.counts["at once"] == 3, service.triage.counts
