"""A shutdown's cancel that arrives as the broker's SUBACK (or CONNACK) is read, or any number of
loop turns after it, against a real mosquitto: the abort connection's session (AbortLink._session)
and the main connection's (BrokerLink._session) end cancelled within a second instead of reading on
until the link drops. (aiomqtt 2.5 waited for the SUBACK and the CONNACK with `asyncio.wait_for`,
which on Python 3.11 took such a cancel and returned as if none came.)"""

from __future__ import annotations

import asyncio
import time

import pytest

from orbitrig.service.abort_link import AbortLink
from orbitrig.service.settings import AbortAccount
from support.mqtt_helpers import ACCOUNTS, Broker, engineless_service

RIG = "subscribe-cancel"


def _cancel_after(answer: str, link, make_client, turns: int, task_of, accepted: list[bool]) -> None:
    """Every client ``make_client`` makes for ``link`` has `task_of()` cancelled `turns` loop turns after
    the broker's ``answer`` (paho's callback: on_subscribe, the SUBACK; on_connect, the CONNACK) is read
    (0: in the read's own turn, after aiomqtt set the result)."""

    def hooked_client(*args, **kwargs):
        client = make_client(*args, **kwargs)
        paho, loop = client._client, asyncio.get_running_loop()
        read = getattr(paho, answer)

        def later(left: int) -> None:
            if left:
                loop.call_soon(later, left - 1)
            elif not accepted:
                accepted.append(task_of().cancel())

        def hooked(*a) -> None:
            read(*a)
            later(turns)

        setattr(paho, answer, hooked)
        return client

    link._client = hooked_client


async def _cancelled_after(answer: str, link, turns: int) -> tuple[bool, float]:
    """`link._session()` cancelled `turns` loop turns after the broker's ``answer`` (_cancel_after):
    whether the session took the cancel, and the s from the cancel to its end."""
    accepted: list[bool] = []
    task: asyncio.Task | None = None
    _cancel_after(answer, link, link._client, turns, lambda: task, accepted)
    task = asyncio.ensure_future(link._session())
    t0 = time.monotonic()
    while not accepted and time.monotonic() - t0 < 5.0:
        await asyncio.sleep(0.01)
    assert accepted, f"no {answer} within 5 s"
    t_cancel = time.monotonic()
    done, _ = await asyncio.wait([task], timeout=2.0)
    if not done:
        task.cancel()  # (the cancel was lost: the session reads on; the test fails below)
        await asyncio.wait([task], timeout=5.0)
    return bool(done), time.monotonic() - t_cancel


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
