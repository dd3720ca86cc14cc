"""drives.waits.first_set, the one wait on asyncio events of the drives and the application: it
returns when an event is set (saying which), times out when due, lets a cancel through at once
(also one arriving as its event fires) leaving no task behind, and loses no event set before it."""

from __future__ import annotations

import asyncio
import time

import pytest

from drives.waits import first_set


def _others() -> set[asyncio.Task]:
    return asyncio.all_tasks() - {asyncio.current_task()}


async def test_returns_the_event_set_during_the_wait_at_once():
    first, second = asyncio.Event(), asyncio.Event()
    asyncio.get_running_loop().call_later(0.05, second.set)
    t0 = time.monotonic()
    fired = await first_set(first, second, timeout=5.0)
    assert fired is second
    assert 0.04 <= time.monotonic() - t0 < 1.0
    await asyncio.sleep(0)  # the wait on `first`, cancelled, has ended
    assert not _others()


async def test_an_event_set_and_cleared_during_the_wait_is_the_one_that_fired():
    tick = asyncio.Event()

    def blink() -> None:
        tick.set()
        tick.clear()  # the next tick's wait begins: the one in flight was still woken

    asyncio.get_running_loop().call_later(0.02, blink)
    assert await first_set(tick, timeout=5.0) is tick


async def test_times_out_when_due_and_says_none_fired():
    event = asyncio.Event()
    t0 = time.monotonic()
    assert await first_set(event, timeout=0.1) is None
    assert 0.09 <= time.monotonic() - t0 < 1.0
    t0 = time.monotonic()
    assert await first_set(event, timeout=-3.0) is None  # no time left: at once
    assert time.monotonic() - t0 < 0.5
    await asyncio.sleep(0)
    assert not _others()


@pytest.mark.parametrize("timeout", [None, 0.0, 5.0])
async def test_an_event_set_before_the_wait_is_not_lost(timeout):
    late, early = asyncio.Event(), asyncio.Event()
    early.set()
    assert await first_set(late, early, timeout=timeout) is early


async def test_an_event_set_before_the_wait_still_lets_the_loop_turn():
    """A loop that waits on an event left set (a poll's tick) cannot starve the loop."""
    event, turned = asyncio.Event(), []
    event.set()
    asyncio.get_running_loop().call_soon(turned.append, True)
    await first_set(event)
    assert turned == [True]


async def test_a_cancel_gets_through_at_once_leaving_no_task():
    events = [asyncio.Event(), asyncio.Event()]
    waiter = asyncio.ensure_future(first_set(*events, timeout=30.0))
    await asyncio.sleep(0.02)
    assert len(_others()) == 3  # the wait and its waits on both events
    t0 = time.monotonic()
    waiter.cancel()
    with pytest.raises(asyncio.CancelledError):
        await waiter
    assert time.monotonic() - t0 < 0.5
    assert not _others()
    assert not any(e._waiters for e in events)  # nobody waits on the events any more


async def test_a_cancel_arriving_as_the_event_fires_is_not_lost():
    """The abort that cancels a wait for standstill in the loop turn the poll's tick fires
    (asyncio.wait_for of Python 3.11 returns the event's result then, the cancel dropped)."""
    for _ in range(20):
        tick = asyncio.Event()
        waiter = asyncio.ensure_future(first_set(tick, timeout=30.0))
        await asyncio.sleep(0)
        tick.set()
        waiter.cancel()
        with pytest.raises(asyncio.CancelledError):
            await waiter
        assert not _others()
