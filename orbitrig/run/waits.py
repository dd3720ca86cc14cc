"""A wait on asyncio events that a cancellation always gets through (not `asyncio.wait_for`, which
can swallow a cancel arriving as its event fires: an abort must never be lost)."""

from __future__ import annotations

import asyncio


async def first_set(*events: asyncio.Event, timeout: float | None = None) -> None:
    """Until one of `events` is set (or `timeout` wall s)."""
    waits = [asyncio.ensure_future(e.wait()) for e in events]
    try:
        await asyncio.wait(waits, timeout=timeout, return_when=asyncio.FIRST_COMPLETED)
    finally:
        for w in waits:
            w.cancel()
