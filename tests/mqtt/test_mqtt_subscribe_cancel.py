"""A shutdown's cancel that arrives as the broker's SUBACK (or CONNACK) is read, or any number of
loop turns after it, against a real mosquitto: the abort connection's session (AbortLink._session)
and the main connection's (BrokerLink._session) end cancelled within a second instead of reading on
until the link drops. (aiomqtt 2.5 waited for the SUBACK and the CONNACK with `asyncio.wait_for`,
which on Python 3.11 took such a cancel and returned as if none came.)"""

from __future__ import annotations

import asyncio

import pytest

from orbitrig.service.abort_link import AbortLink
from orbitrig.service.settings import AbortAccount
from support.cancel_turns import cancel_after, ended_after_cancel
from support.mqtt_helpers import ACCOUNTS, Broker, engineless_service

RIG = "subscribe-cancel"


async def _cancelled_after(answer: str, link, turns: int) -> tuple[bool, float]:
    """`link._session()` cancelled `turns` loop turns after the broker's ``answer`` (cancel_after):
    whether the session ended, and the s from the cancel to its end."""
    accepted: list[bool] = []
    task: asyncio.Task | None = None
    link._client = cancel_after(answer, link._client, turns, lambda: task, accepted)
    task = asyncio.ensure_future(link._session())
    return await ended_after_cancel(task, accepted, answer)


def _abort_link(broker: Broker, tmp_path) -> AbortLink:
    service = engineless_service(broker.url, tmp_path, RIG)
    account = AbortAccount("orbitrig-service-abort", ACCOUNTS["orbitrig-service-abort"])
    return AbortLink(service.link.broker, account, service.settings, service.topics, service.triage)


@pytest.mark.parametrize("turns", range(8))
async def test_the_abort_connection_ends_on_a_cancel_that_comes_with_its_suback(broker: Broker, tmp_path, turns):
    link = _abort_link(broker, tmp_path)
    ended, took = await _cancelled_after("on_subscribe", link, turns)
    assert ended, f"the abort connection read on after a cancel {turns} loop turns after its SUBACK"
    assert took < 1.0
    assert not link.up and not link.subscribed


@pytest.mark.parametrize("turns", range(8))
async def test_the_abort_connection_ends_on_a_cancel_that_comes_with_its_connack(broker: Broker, tmp_path, turns):
    link = _abort_link(broker, tmp_path)
    ended, took = await _cancelled_after("on_connect", link, turns)
    assert ended, f"the abort connection went on after a cancel {turns} loop turns after its CONNACK"
    assert took < 1.0
    assert not link.up and not link.subscribed


@pytest.mark.parametrize("turns", range(8))
async def test_the_main_connection_ends_on_a_cancel_that_comes_with_its_suback(broker: Broker, tmp_path, turns):
    link = engineless_service(broker.url, tmp_path, RIG).link
    ended, took = await _cancelled_after("on_subscribe", link, turns)
    assert ended, f"the main connection went on after a cancel {turns} loop turns after its SUBACK"
    assert took < 1.0
    assert link.offline.is_set() and not link.online.is_set()
