"""drives.waits.first_set, the one wait on asyncio events of the drives and the application: it
returns when an event is set (saying which), times out when due, lets a cancel through at once
(also one arriving as its event fires) leaving no task behind, and loses no event set before it."""

from __future__ import annotations

import asyncio
import sys
import time

import pytest

from drives.waits import done_or_set, first_set


def _others() -> set[asyncio.Task]:
    return asyncio.all_tasks() - {asyncio.current_task()}


async def test_returns_the_event_set_during_the_wait_at_once():
    first, second = asyncio.Event(), asyncio.Event()
    t0 = time.monotonic()  # before the timer is set: a stall between them cannot shorten the wait measured
    asyncio.get_running_loop().call_later(0.05, second.set)
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


async def test_an_event_set_in_the_turn_the_time_runs_out_is_the_answer():
    """The time runs out and, later in the same loop turn, the interlock trips: the wait ends
    with the event set, so the answer is the event (its own wait had not yet woken), never None."""
    loop = asyncio.get_running_loop()
    for wait in (first_set, lambda *e, timeout: done_or_set(loop.create_future(), *e, timeout=timeout)):
        late, trip = asyncio.Event(), asyncio.Event()
        waiter = asyncio.ensure_future(wait(late, trip, timeout=0.0))
        await asyncio.sleep(0)  # the wait has begun: its timer is due in the next turn
        loop.call_later(0.0, trip.set)  # due in that same turn, after the timer
        assert await waiter is trip
        assert trip.is_set() and not late.is_set()
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


async def test_done_or_set_says_the_future_done_and_leaves_it_to_the_caller():
    loop = asyncio.get_running_loop()
    future, event = loop.create_future(), asyncio.Event()
    t0 = time.monotonic()  # before the timer is set (as above)
    loop.call_later(0.05, future.set_result, 7)
    assert await done_or_set(future, event, timeout=5.0) is future
    assert 0.04 <= time.monotonic() - t0 < 1.0
    assert future.result() == 7
    await asyncio.sleep(0)
    assert not _others()


async def test_done_or_set_says_the_event_set_first_and_leaves_the_future_running():
    loop = asyncio.get_running_loop()
    future, first, second = loop.create_future(), asyncio.Event(), asyncio.Event()
    loop.call_later(0.05, second.set)
    assert await done_or_set(future, first, second, timeout=5.0) is second
    assert not future.done()  # the caller's: not cancelled
    t0 = time.monotonic()
    assert await done_or_set(future, first, timeout=0.1) is None  # neither: the time ran out
    assert 0.09 <= time.monotonic() - t0 < 1.0
    assert not future.done()
    future.cancel()


async def test_done_or_set_the_future_comes_first_over_an_event_of_the_same_turn():
    """The point's acquisition done and the interlock's trip in the same turn: the acquisition counts."""
    loop = asyncio.get_running_loop()
    future, event = loop.create_future(), asyncio.Event()
    future.set_result(1)
    event.set()
    assert await done_or_set(future, event, timeout=5.0) is future


async def test_done_or_set_a_cancel_arriving_as_the_future_ends_is_not_lost():
    """The abort that cancels the wait for a ramp stop (or a free-space check) in the loop turn the
    ramp ends: the cancel is raised (asyncio.wait_for of Python 3.11 returned the result, the cancel dropped)."""
    loop = asyncio.get_running_loop()
    for _ in range(20):
        future, event = loop.create_future(), asyncio.Event()
        waiter = asyncio.ensure_future(done_or_set(future, event, timeout=30.0))
        await asyncio.sleep(0)
        future.set_result("standstill")
        waiter.cancel()
        with pytest.raises(asyncio.CancelledError):
            await waiter
        assert not future.cancelled()  # the caller's future is not cancelled by the wait's cancel
        assert not _others()
        assert not event._waiters


async def test_wait_for_of_this_python_drops_such_a_cancel():
    """Why the waits above are not asyncio.wait_for: on the Python the rig runs (3.11) the same race
    returns the future's result and the cancel is gone (3.12 raises it: nothing to drop there)."""
    loop = asyncio.get_running_loop()
    future = loop.create_future()
    waiter = asyncio.ensure_future(asyncio.wait_for(future, 30.0))
    await asyncio.sleep(0)
    future.set_result("standstill")
    waiter.cancel()
    if sys.version_info >= (3, 12):
        with pytest.raises(asyncio.CancelledError):
            await waiter
    else:
        assert await waiter == "standstill"
