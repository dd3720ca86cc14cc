"""Is the event loop free? A task that notes the time every 10 ms: a loop held by a blocking
call (a disk write, a statvfs) shows as a gap, or as no beat within a window."""

from __future__ import annotations

import asyncio
import time


class LoopBeats:
    """`async with LoopBeats() as beats:` beats while the block runs (monotonic s)."""

    def __init__(self, period: float = 0.01):
        self.period, self.times = period, []
        self._task: asyncio.Task[None] | None = None

    async def _beat(self) -> None:
        while True:
            self.times.append(time.monotonic())
            await asyncio.sleep(self.period)

    async def __aenter__(self) -> LoopBeats:
        self._task = asyncio.create_task(self._beat())
        return self

    async def __aexit__(self, *exc) -> None:
        assert self._task is not None
        self._task.cancel()
        await asyncio.gather(self._task, return_exceptions=True)

    def within(self, start: float, end: float) -> int:
        """Beats strictly between `start` and `end` (a loop held all along: none)."""
        return sum(start < t < end for t in self.times)

    def longest_gap(self) -> float:
        """The longest time between two beats so far (s)."""
        return max((b - a for a, b in zip(self.times, self.times[1:])), default=0.0)
