"""A wait on the rig that an interlock suspension cuts short.

`guarded(aw, sup)` awaits ``aw`` (the drives settling, an A/D acquisition) unless the
supervisor's suspend trip comes first: then ``aw`` is cancelled and `Suspended` raised,
carrying the trip; the point procedure holds the run until the trip clears
(`RunControl.hold_while_suspended`) and settles and acquires the block again.
"""

from __future__ import annotations

import asyncio
from typing import Awaitable, TypeVar

from drives.waits import done_or_set

from orbitrig.run.interlocks import SUSPEND, Trip, TripKind
from orbitrig.run.supervision import InterlockSupervisor

T = TypeVar("T")


class Suspended(Exception):
    """An interlock tripped while the engine waited for the drives or the A/D board."""

    def __init__(self, trip: Trip):
        super().__init__(trip.message)
        self.trip = trip


async def guarded(aw: Awaitable[T], sup: InterlockSupervisor) -> T:
    """Await `aw`; Suspended (and `aw` cancelled) if an interlock suspends the run meanwhile."""
    task = asyncio.ensure_future(aw)
    try:
        if await done_or_set(task, sup.tripped) is task:
            return task.result()
        raise Suspended(sup.trip or Trip(TripKind.INTERLOCK, SUSPEND, "interlock"))
    finally:
        if not task.done():
            task.cancel()
        await asyncio.gather(task, return_exceptions=True)
