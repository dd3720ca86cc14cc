"""A wait on asyncio events that a cancellation always gets through (not `asyncio.wait_for`,
which in Python 3.11 can drop a cancel arriving as its event fires: an abort that cancels a wait
for standstill, for the setpoint or for an interlock to clear must never be lost).

The one owner of that wait for the drives and the application (orbitrig imports drives, never
the other way round; daq waits on no event)."""

from __future__ import annotations

import asyncio


async def first_set(*events: asyncio.Event, timeout: float | None = None) -> asyncio.Event | None:
    """Until one of `events` is set, or `timeout` wall s (negative: none left); the first of
    `events` (in the order given) found set during the wait, None once the time ran out. An event
    set before the call ends it at the first turn of the loop (the wait always yields once); a
    cancellation is raised at once, the waits on the events cancelled (no task left behind)."""
    waits = [asyncio.ensure_future(e.wait()) for e in events]
    try:
        limit = None if timeout is None else max(0.0, timeout)
        await asyncio.wait(waits, timeout=limit, return_when=asyncio.FIRST_COMPLETED)
        return next((e for e, w in zip(events, waits) if w.done() and not w.cancelled()), None)
    finally:
        for w in waits:
            w.cancel()
