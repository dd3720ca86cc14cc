"""The waits on asyncio events that a cancellation always gets through (not `asyncio.wait_for`,
which in Python 3.11 can drop a cancel arriving as what it waits for ends: an abort that cancels a
wait for standstill, for the setpoint, for an interlock to clear or for a ramp stop must never be
lost). `first_set`: until an event is set; `done_or_set`: until a future is done or an event set.

The one owner of these waits for the drives and the application (orbitrig imports drives, never
the other way round; daq's one wait on an event, AuxSensors.heard, is bounded by asyncio.timeout)."""

from __future__ import annotations

import asyncio
from typing import Any


async def first_set(*events: asyncio.Event, timeout: float | None = None) -> asyncio.Event | None:
    """Until one of `events` is set, or `timeout` wall s (negative: none left); the first of
    `events` (in the order given) set as the wait ends (or set during it), None if none was. An event
    set before the call ends it at the first turn of the loop (the wait always yields once); a
    cancellation is raised at once, the waits on the events cancelled (no task left behind)."""
    fired = await _first_of(None, events, timeout)
    return fired if isinstance(fired, asyncio.Event) else None


async def done_or_set(
    future: asyncio.Future[Any], *events: asyncio.Event, timeout: float | None = None
) -> asyncio.Future[Any] | asyncio.Event | None:
    """Until `future` is done or one of `events` is set, or `timeout` wall s (negative: none
    left); `future` if it is done (it comes first, also when an event was set in the same turn),
    else the first of `events` set as the wait ends (or set during it), else None. `future` is the caller's:
    never cancelled here, its result not read. Otherwise as `first_set` (always yields once; a
    cancellation raised at once, also one arriving as `future` ends; no task left behind)."""
    return await _first_of(future, events, timeout)


async def _first_of(
    future: asyncio.Future[Any] | None, events: tuple[asyncio.Event, ...], timeout: float | None
) -> asyncio.Future[Any] | asyncio.Event | None:
    """After a wait on them (asyncio.wait: a cancellation raised, never swallowed) of at most
    `timeout` s: `future` if done, else the first of `events` (in the order given) that is set as
    the wait ends or whose wait woke (set and cleared again during it), else None. An event set in
    the turn the time ran out counts, though its own wait has not woken yet."""
    waits = [asyncio.ensure_future(e.wait()) for e in events]
    try:
        limit = None if timeout is None else max(0.0, timeout)
        await asyncio.wait(
            waits + ([] if future is None else [future]), timeout=limit, return_when=asyncio.FIRST_COMPLETED
        )
        if future is not None and future.done():
            return future
        return next((e for e, w in zip(events, waits) if e.is_set() or (w.done() and not w.cancelled())), None)
    finally:
        for w in waits:
            w.cancel()
