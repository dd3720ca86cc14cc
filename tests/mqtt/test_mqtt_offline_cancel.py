"""The service's ``offline`` on its way out (BrokerLink._say_offline, the shutdown's and the clean
session's), against a real mosquitto: a cancel of the service's exit (a second signal, the grace
run out) that arrives as the broker's acknowledgement is read, or any number of loop turns
after it, is raised if the wait took it; the ``offline`` is delivered either way. (On Python 3.11
`asyncio.wait_for`, ours and aiomqtt's own, took such a cancel and returned as if none came.)"""

from __future__ import annotations

import asyncio
import time

import pytest

from support.cancel_turns import hook_answer
from support.mqtt_helpers import Broker, engineless_service, retained, wait

RIG = "offline-cancel"


@pytest.mark.parametrize("turns", range(8))
async def test_a_cancel_arriving_with_the_offline_acknowledged_is_raised(broker: Broker, tmp_path, turns):
    link = engineless_service(broker.url, tmp_path, RIG).link
    async with link._client(clean_start=True) as client:
        accepted: list[bool] = []
        task: asyncio.Task | None = None
        hook_answer(client._client, "on_publish", turns, lambda: task, accepted)
        t0 = time.monotonic()
        task = asyncio.ensure_future(link._say_offline(client))
        done, _ = await asyncio.wait([task], timeout=5.0)
        assert done, "the offline was not acknowledged within 5 s"
        for _ in range(turns + 1):
            await asyncio.sleep(0)  # the cancel goes out: the task may have ended before
        assert accepted  # the PUBACK was read and the cancel sent
        if accepted[0]:  # the wait took the cancel: the exit goes on being cancelled
            assert task.cancelled()
        else:  # the cancel came after the offline was said
            assert task.result() is None and link.said_offline
        assert time.monotonic() - t0 < 3.0
    msg = await wait(retained, broker, link.topics.status)
    assert msg is not None and msg.json()["state"] == "offline"
