"""A rig chosen whose subscription the broker does not confirm, on a real mosquitto (orbitrig.dashboard.session,
Session._resubscribe): the session keeps trying with a growing delay while its link stays up, and meanwhile reads
the rig's status from the rigs' copy (`orbitrig/+/status`, catchup.Via.RIGS), so that the page is never blind;
once subscribed each status reaches the page once, with no reconnection.

A SUBACK that never comes is the fault a real mosquitto does not make on demand: it is put at the broker_calls
seam, for the new rig's subscriptions only (the SUBSCRIBE not sent, or sent and its SUBACK given up on)."""

from __future__ import annotations

import asyncio
import json
import time

import aiomqtt
import pytest
from support.mqtt_helpers import ACCOUNTS, Broker, CutProxy

import orbitrig.service.broker_calls as broker_calls
import orbitrig.service.protocol as proto
from orbitrig.dashboard.catchup import Via, subscriptions
from orbitrig.dashboard.feed import BrokerLink, Feed, FeedType
from orbitrig.dashboard.session import DashboardSettings, Session

A, B = "resub-a", "resub-b"


def status(n: int) -> dict:
    return {"state": "running", "run_id": "r-resub", "since": f"2026-12-07T20:0{n}:00.000Z", "message": f"s{n}"}


class NoSuback:
    """broker_calls.subscribe, but the subscription to rig B's topics is not confirmed while ``held``: ``sent``
    False: the SUBSCRIBE never goes (the broker never subscribes); True: it goes, its SUBACK is given up on."""

    def __init__(self, sent: bool) -> None:
        self.real, self.sent = broker_calls.subscribe, sent
        self.held = True
        self.attempts = 0  # SUBSCRIBEs to rig B's topics asked for
        self.at: list[float] = []  # time.monotonic() of each
        self.confirmed = asyncio.Event()

    async def __call__(self, client, topic, qos: int = 0, **kw):
        if topic != subscriptions(proto.topics(B)):
            return await self.real(client, topic, qos, **kw)
        self.attempts += 1
        self.at.append(time.monotonic())
        if self.held:
            if self.sent:
                await self.real(client, topic, qos, **kw)
            raise aiomqtt.MqttError(broker_calls.TIMED_OUT)
        codes = await self.real(client, topic, qos, **kw)
        self.confirmed.set()
        return codes


async def pub(broker: Broker, leaf: str, body: dict, retain: bool = False) -> None:
    done = await asyncio.to_thread(
        broker.pub, f"orbitrig/{B}/{leaf}", json.dumps(body), user="orbitrig-service", retain=retain
    )
    assert done.returncode == 0, done.stderr


async def until(feed: Feed, got: list[dict], done, timeout: float = 10.0) -> None:
    """Messages of ``feed`` into ``got`` until ``done(got)``."""
    async with asyncio.timeout(timeout):
        while not done(got):
            got += await feed.take()


def statuses(got: list[dict]) -> list[dict]:
    return [m["data"] for m in got if m["type"] == FeedType.STATUS]


async def signed_in(broker: Broker, port: int | None = None) -> tuple[Session, Feed]:
    """A session watching rig A, on the broker or a relay to it at ``port``, and a page's feed of it."""
    settings = DashboardSettings(host="127.0.0.1", port=port or broker.port, topics=proto.topics(A))
    session = Session(settings, "viewer", ACCOUNTS["viewer"])
    await session.open()
    feed = Feed()
    session.feeds.add(feed)
    return session, feed


@pytest.mark.parametrize("sent", [False, True], ids=["subscribe-lost", "suback-lost"])
async def test_a_rig_chosen_without_suback_is_read_and_subscribed_again(broker: Broker, monkeypatch, sent):
    await pub(broker, "status", status(0), retain=True)  # rig B's present status, before it is chosen
    fault = NoSuback(sent)
    monkeypatch.setattr(broker_calls, "subscribe", fault)
    session, feed = await signed_in(broker)
    client, got = session._client, []
    try:
        async with asyncio.timeout(10):  # the page chooses a rig of the listing
            while session.rigs.latest.get(B) != status(0):
                await asyncio.sleep(0.01)
        assert (await session.select_rig(B))["ok"]
        await until(feed, got, lambda g: status(0) in statuses(g))  # the rig's status as listed
        assert session._resubscribing is not None and session._subscribed != proto.topics(B)
        await pub(broker, "status", status(1), retain=True)
        await until(feed, got, lambda g: status(1) in statuses(g))  # unconfirmed: read from the rigs' copy
        assert fault.attempts >= 1 and not fault.confirmed.is_set()
        fault.held = False
        async with asyncio.timeout(15):  # the next attempt: within 0.5 + 1 + 2 + 4 + 5 s of backoff
            await fault.confirmed.wait()
            while session._subscribed != proto.topics(B):
                await asyncio.sleep(0.01)
        await pub(broker, "status", status(2), retain=True)
        await pub(broker, "status", status(3), retain=True)
        await pub(broker, "note", {"run_id": "r-resub", "message": "after"})  # comes by rig B's own subscription
        await until(feed, got, lambda g: any(m["type"] == FeedType.NOTE for m in g))
        await asyncio.sleep(0.3)  # a copy said twice would follow at once
        if feed.wake.is_set():
            got += await feed.take()
        assert session._client is client  # no reconnection
    finally:
        await session.close("signed out")
    ours = [s for s in statuses(got) if s.get("run_id") == "r-resub"]
    assert ours == [status(0), status(1), status(2), status(3)], ours  # each once
    assert not any(m["type"] == FeedType.LINK for m in got)


async def test_a_rig_chosen_is_shown_as_listed_before_the_broker_confirms_it(broker: Broker, monkeypatch):
    await pub(broker, "status", status(0), retain=True)
    real, let_go = broker_calls.subscribe, asyncio.Event()

    async def late(client, topic, qos: int = 0, **kw):  # the SUBSCRIBE to rig B goes only once let go
        if topic == subscriptions(proto.topics(B)):
            await let_go.wait()
        return await real(client, topic, qos, **kw)

    monkeypatch.setattr(broker_calls, "subscribe", late)
    session, feed = await signed_in(broker)
    got: list[dict] = []
    try:
        async with asyncio.timeout(10):
            while session.rigs.latest.get(B) != status(0):
                await asyncio.sleep(0.01)
        choosing = asyncio.create_task(session.select_rig(B))
        await until(feed, got, lambda g: status(0) in statuses(g))  # before its subscription is made
        assert not choosing.done()
        let_go.set()
        assert (await choosing)["ok"] and session._subscribed == proto.topics(B)
        await pub(broker, "status", status(1), retain=True)
        await until(feed, got, lambda g: status(1) in statuses(g))
        await asyncio.sleep(0.3)  # a copy said twice would follow at once
        if feed.wake.is_set():
            got += await feed.take()
    finally:
        await session.close("signed out")
    ours = [s for s in statuses(got) if s.get("run_id") == "r-resub"]
    assert ours == [status(0), status(1)], ours  # the retained copy its subscription handed on: not sent again


async def test_trying_again_ends_with_another_rig_and_with_the_session(broker: Broker, monkeypatch):
    fault = NoSuback(sent=False)
    monkeypatch.setattr(broker_calls, "subscribe", fault)
    session, _ = await signed_in(broker)
    try:
        assert (await session.select_rig(B))["ok"]
        first = session._resubscribing
        assert first is not None and not first.done()
        assert (await session.select_rig(A))["ok"]  # another rig: confirmed, no more attempts for B
        await asyncio.sleep(0)
        assert first.done() and session._resubscribing is None
        assert session._subscribed == proto.topics(A)
        assert (await session.select_rig(B))["ok"]
        second = session._resubscribing
        assert second is not None
        moved = fault.attempts  # the last: the move's own SUBSCRIBE
        async with asyncio.timeout(20):  # three attempts more: 0.25 to 0.5 s, 0.5 to 1 s, 1 to 2 s apart
            while fault.attempts < moved + 3:
                await asyncio.sleep(0.05)
        gaps = [b - a for a, b in zip(fault.at[moved - 1 :], fault.at[moved:])]
        assert all(gap > 0.95 * least for gap, least in zip(gaps, (0.25, 0.5, 1.0))), gaps  # doubling, never sooner
    finally:
        await session.close("signed out")
    assert second.done() and session._resubscribing is None  # no task left behind
    attempts = fault.attempts
    await asyncio.sleep(1.5)
    assert fault.attempts == attempts


async def test_trying_again_ends_with_the_link_and_the_reconnection_subscribes_the_rig(broker: Broker, monkeypatch):
    fault = NoSuback(sent=False)
    monkeypatch.setattr(broker_calls, "subscribe", fault)
    way = CutProxy(broker.port)  # the session's way to the broker
    session, _ = await signed_in(broker, way.port)
    try:
        assert (await session.select_rig(B))["ok"]
        trying = session._resubscribing
        assert trying is not None and not trying.done()
        way.cut()  # the link drops, and no new one comes up meanwhile
        async with asyncio.timeout(15):  # given up at its next attempt (at most 5 s apart)
            while not trying.done():
                await asyncio.sleep(0.05)
        attempts = fault.attempts
        fault.held = False
        way.restore()
        async with asyncio.timeout(30):  # the reconnection subscribes to the rig watched
            while session.link != BrokerLink.ONLINE or session._subscribed != proto.topics(B):
                await asyncio.sleep(0.05)
        assert fault.attempts == attempts + 1 and session._resubscribing is None  # its one SUBSCRIBE, no retries
    finally:
        await session.close("signed out")
        way.close()


async def test_each_attempts_retained_copy_of_a_status_reaches_the_pages_once():
    """Each SUBSCRIBE attempt has the broker hand on the rig's retained status, and an attempt given up on may
    have its copy come after the next began: while unconfirmed, each status read is expected again, so no copy
    of it is sent twice; once confirmed the next status is read as ever. The copies, as mosquitto hands them on,
    go straight to the session's reading: their crossing is the fault a real broker does not make on demand."""
    session = Session(DashboardSettings(host="127.0.0.1", port=1, topics=proto.topics(A)), "viewer", "-")
    feed = Feed()
    session.feeds.add(feed)
    assert (await session.select_rig(B))["ok"]  # no link: the rig's subscription not confirmed
    watched, rigs = frozenset({Via.WATCHED}), frozenset({Via.RIGS})

    def heard(n: int, via: frozenset[int]) -> None:
        session._on_message(proto.topics(B).status, json.dumps(status(n)), via)

    heard(0, rigs)  # the rigs' copy, read while unconfirmed
    heard(0, watched)  # attempt 1's retained copy
    heard(0, watched)  # attempt 2's, come after it began
    heard(1, watched)  # a new status by the rig's own subscription
    heard(1, rigs)  # its rigs' copy: listed only
    heard(1, watched)  # attempt 3's retained copy of it
    session._subscribed = proto.topics(B)  # attempt 3 confirmed
    heard(1, watched)  # a retained copy of attempt 3 come late
    heard(2, watched)
    heard(2, rigs)
    got = await feed.take(1000)
    assert statuses(got) == [status(0), status(1), status(2)], statuses(got)
    assert session.status_expected is None  # confirmed: what comes next is read as ever
