"""A cancel timed against the broker's answers on a real connection: `task_of()` cancelled a given
number of event-loop turns after paho read the broker's CONNACK, SUBACK or PUBACK (aiomqtt's waits
for them were `asyncio.wait_for`, which on Python 3.11 took such a cancel and returned as if none
came)."""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from typing import Any


def cancel_after(answer: str, make_client: Callable[..., Any], turns: int, task_of, accepted: list[bool]):
    """``make_client`` made into one whose every client has `task_of()` cancelled `turns` loop turns
    after the broker's ``answer`` (paho's callback: on_connect, on_subscribe, on_publish) is read (0: in
    the read's own turn, after aiomqtt took the answer); whether the task took the cancel, to
    `accepted` (once)."""

    def hooked_client(*args, **kwargs):
        client = make_client(*args, **kwargs)
        hook_answer(client._client, answer, turns, task_of, accepted)
        return client

    return hooked_client


def hook_answer(paho: Any, answer: str, turns: int, task_of, accepted: list[bool]) -> None:
    """The `paho` client's ``answer`` callback (on_connect, on_subscribe, on_publish) made to cancel
    `task_of()` `turns` loop turns after the broker's answer is read (0: in the read's own turn, after
    the client took it); whether the task took the cancel, to `accepted` (once)."""
    loop = asyncio.get_running_loop()
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


async def ended_after_cancel(task: asyncio.Task, accepted: list[bool], answer: str) -> tuple[bool, float]:
    """Once the cancel of `cancel_after` went out: whether `task` ended within 2 s of it, and the s it
    took (a task that did not end is cancelled again: the test goes on)."""
    t0 = time.monotonic()
    while not accepted and time.monotonic() - t0 < 5.0:
        await asyncio.sleep(0.01)
    assert accepted, f"no {answer} within 5 s"
    t_cancel = time.monotonic()
    done, _ = await asyncio.wait([task], timeout=2.0)
    took = time.monotonic() - t_cancel
    if not done:
        task.cancel()  # (the cancel was lost)
        await asyncio.wait([task], timeout=5.0)
    return bool(done), took
