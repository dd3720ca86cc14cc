"""A dashboard session's reading of a last will around a broker outage (orbitrig.dashboard.link_lost), on a real
authenticated mosquitto reached through a relay the tests cut (the dashboard's own link lost, the broker up): the
grace timer that sends the pages the reading once WILL_NEAR_OUTAGE_S after the link is back, across outages one after
the other and a sign-out; a rig chosen after an outage whose retained last will was listed long before it; a will in
words not the service's own."""

from __future__ import annotations

import asyncio
import json
import time
from collections.abc import Callable

import pytest
from support.mqtt_helpers import ACCOUNTS

import orbitrig.dashboard.link_lost as link_lost_module
import orbitrig.dashboard.session as session_module
from orbitrig.dashboard.feed import BrokerLink, Feed, FeedType
from orbitrig.dashboard.session import DashboardSettings, Session
from orbitrig.service import protocol as proto

#: s a message the session sends may take with both cores busy
SENT_WITHIN_S = 20.0

WILL = {
    "state": "offline",
    "run_id": None,
    "since": "2026-12-05T00:59:00.000Z",
    "message": "connection to the rig service lost",
    "last_will": "the broker published this last will, registered when the service connected (2026-12-05T00:59:00.000Z)",
}


async def next_message(feed: Feed, pred: Callable[[dict], bool], within: float = SENT_WITHIN_S) -> dict:
    """The feed's first message for which ``pred`` holds, waited for (at most ``within`` s)."""
    deadline = time.monotonic() + within
    while True:
        left = deadline - time.monotonic()
        assert left > 0, "no such message"
        for message in await asyncio.wait_for(feed.take(), left):
            if pred(message):
                return message


def is_link(link: BrokerLink) -> Callable[[dict], bool]:
    return lambda m: m["type"] == FeedType.LINK and m["link"] == link


async def outage(relay, feed: Feed) -> None:
    """The session's link cut (the broker up) and back."""
    relay.cut()
    await next_message(feed, is_link(BrokerLink.UNREACHABLE))
    relay.restore()
    await next_message(feed, is_link(BrokerLink.ONLINE))


def operator_session(relay, rig: str) -> tuple[Session, Feed]:
    settings = DashboardSettings(host="127.0.0.1", port=relay.port, topics=proto.topics(rig))
    session, feed = Session(settings, "operator", ACCOUNTS["operator"]), Feed()
    session.feeds.add(feed)
    return session, feed


async def test_no_grace_of_an_outage_goes_to_the_pages_after_sign_out(broker, relay, monkeypatch):
    """Two outages one after the other, then sign-out within the grace: nothing more goes to the pages after
    `signed_out`. Before, the first outage's timer (not cancelled when the second came) sent the rigs listed
    to the pages of a session signed out, WILL_NEAR_OUTAGE_S after its link was first back."""
    grace = 2.0
    monkeypatch.setattr(session_module, "WILL_NEAR_OUTAGE_S", grace)
    session, feed = operator_session(relay, "rig-grace")
    await session.open()
    await next_message(feed, is_link(BrokerLink.ONLINE))
    await outage(relay, feed)
    first_back = time.monotonic()
    await outage(relay, feed)
    await session.close("signed out")
    assert [m["type"] for m in await asyncio.wait_for(feed.take(), 1.0)][-1] == FeedType.SIGNED_OUT
    after = asyncio.create_task(feed.take())
    done, _ = await asyncio.wait({after}, timeout=max(0.5, first_back + grace + 1.0 - time.monotonic()))
    after.cancel()
    assert not done, after.result()


async def test_a_rig_chosen_after_an_outage_its_last_will_listed_long_before_is_offline(broker, relay):
    """The session listed another rig's retained last will long before an outage (as offline: it did not come with
    the outage); chosen while the link is down, that rig's status comes as the link is back: it is read as listed,
    `offline`, in the status sent to the pages, in the rigs listed and in a refused Start alike. Before, the badge
    said `unknown — link lost` for 10 s while the selector said `offline` (its will taken as heard as it came again)."""
    done = broker.pub("orbitrig/rig-old/status", json.dumps(WILL), user="orbitrig-service", retain=True)
    assert done.returncode == 0, done.stderr
    session, feed = operator_session(relay, "rig-new")
    await session.open()
    try:
        await next_message(feed, lambda m: m["type"] == FeedType.RIGS and "rig-old" in m["data"])
        session.rigs.heard_at["rig-old"] -= 60.0  # listed a minute before the outage (not waited for)
        relay.cut()
        await next_message(feed, is_link(BrokerLink.UNREACHABLE))
        assert (await session.select_rig("rig-old"))["ok"]
        relay.restore()
        status = await next_message(feed, lambda m: m["type"] == FeedType.STATUS and m["data"].get("last_will"))
        assert status["link_lost"] is False, status
        listed = next(m for m in session.snapshot() if m["type"] == FeedType.RIGS)  # as a page (re)loaded gets it
        assert listed["data"]["rig-old"]["link_lost"] is False
        refused = await session.command({"cmd": "start", "rig": "orbitrig/rig-old", "matrix": "demo"})
        assert (refused["ok"], refused["error"]) == (False, "not sent: the rig service is offline"), refused
    finally:
        await session.close("signed out")


@pytest.fixture(autouse=True)
def _relay_open(relay):
    """Each test begins with the way to the broker open."""
    relay.restore()
    yield
    relay.restore()


async def test_a_will_of_its_own_words_is_read_by_its_last_will_field_and_keeps_them(broker, relay, monkeypatch):
    """A last will whose message is not this service's (another build's, another rig service's words) is told by
    its `last_will` field alone: heard as the link is back, `link_lost` until the grace is over, then `offline`
    with its own message, the status said again as it was heard."""
    grace = 3.0  # s: the will's reading sent with it well within it, both cores busy
    monkeypatch.setattr(session_module, "WILL_NEAR_OUTAGE_S", grace)
    monkeypatch.setattr(link_lost_module, "WILL_NEAR_OUTAGE_S", grace)
    running = {"state": "running", "run_id": "r-own", "since": "2026-12-05T01:00:00.000Z", "message": "run"}
    will = {**WILL, "message": "keepalive expired: rig PC unreachable"}
    assert (
        broker.pub("orbitrig/rig-own/status", json.dumps(running), user="orbitrig-service", retain=True).returncode == 0
    )
    session, feed = operator_session(relay, "rig-own")
    await session.open()
    try:
        await next_message(feed, lambda m: m["type"] == FeedType.STATUS and m["data"]["state"] == "running")
        relay.cut()
        await next_message(feed, is_link(BrokerLink.UNREACHABLE))
        assert (
            broker.pub("orbitrig/rig-own/status", json.dumps(will), user="orbitrig-service", retain=True).returncode
            == 0
        )
        relay.restore()
        heard = await next_message(feed, lambda m: m["type"] == FeedType.STATUS and m["data"].get("last_will"))
        assert heard["link_lost"] is True and heard["data"] == will
        said = await next_message(feed, lambda m: m["type"] == FeedType.STATUS and not m["link_lost"])
        assert said["data"] == will  # the will's own words, as heard
    finally:
        await session.close("signed out")
