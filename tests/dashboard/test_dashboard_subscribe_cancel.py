"""A sign-out's cancel of a dashboard session's connection that arrives as the broker's SUBACK is
read, or any number of loop turns after it (real mosquitto): the connection ends within a second,
not reading on until the link drops (``Session.close`` awaits it). aiomqtt 2.5 waited for the
SUBACK with `asyncio.wait_for`, which on Python 3.11 took such a cancel and returned as if none came."""

from __future__ import annotations

import asyncio

import pytest

import orbitrig.service.protocol as proto
from orbitrig.dashboard.session import DashboardSettings, Session
from support.cancel_turns import cancel_after, ended_after_cancel
from support.mqtt_helpers import ACCOUNTS, Broker


@pytest.mark.parametrize("turns", range(8))
async def test_a_dashboard_connection_ends_on_a_cancel_that_comes_with_its_suback(broker: Broker, turns):
    settings = DashboardSettings(host="127.0.0.1", port=broker.port, topics=proto.topics("subscribe-cancel"))
    session = Session(settings, "operator", ACCOUNTS["operator"])
    accepted: list[bool] = []
    task: asyncio.Task | None = None
    session._make_client = cancel_after("on_subscribe", session._make_client, turns, lambda: task, accepted)
    first: asyncio.Future = asyncio.get_running_loop().create_future()
    task = asyncio.ensure_future(session._connection(first))
    ended, took = await ended_after_cancel(task, accepted, "SUBACK")
    assert ended, f"the dashboard's connection read on after a cancel {turns} loop turns after its SUBACK"
    assert took < 1.0
    assert task.cancelled()
