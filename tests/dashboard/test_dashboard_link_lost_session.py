"""A dashboard session's reading of a last will around a broker outage (orbitrig.dashboard.link_lost), on a real
authenticated mosquitto reached through a relay the tests cut (the dashboard's own link lost, the broker up): the
grace timer that sends the pages the reading once WILL_NEAR_OUTAGE_S after the link is back, across outages one after
the other and a sign-out."""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable

import pytest
from support.mqtt_helpers import ACCOUNTS

import orbitrig.dashboard.session as session_module
from orbitrig.dashboard.feed import BrokerLink, Feed, FeedType
from orbitrig.dashboard.session import DashboardSettings, Session
from orbitrig.service import protocol as proto

#: s a message the session sends may take with both cores busy
SENT_WITHIN_S = 20.0


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


@pytest.fixture(autouse=True)
def _relay_open(relay):
    """Each test begins with the way to the broker open."""
    relay.restore()
    yield
    relay.restore()
