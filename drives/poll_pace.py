"""When the drive poll reads the drives: at a steady pace, and sooner when asked; when a
condition read by the polls has held long enough (`SettleDetector`).

The poll is the drives' heartbeat, so it keeps its pace (every `interval` s; a late poll is
not made up). The wait for the setpoint asks for extra polls (`PollPace.ask`): one right
after a speed command (or when its caller expects the ramps over), one every quarter interval
(a tenth of a shorter hold) until both drives are at their setpoints, and one when the hold
would end, so the hold is judged on statuses read then, not up to an interval later.
"""

from __future__ import annotations

import asyncio
import time

from drives.waits import first_set


def read_again_by(at: float, interval: float, timeout: float) -> float:
    """Monotonic s by which a drive has been read by a poll asked after `at` (monotonic s): two
    polls of `interval` s and a request's `timeout` later (the poll in flight at `at` may have
    been asked before it)."""
    return at + 2 * interval + timeout


class PollPace:
    """The times of the polls: every `interval` s (monotonic), and any asked for in between."""

    def __init__(self, interval: float):
        self.interval = interval
        self._due: float | None = None  # the next poll at the pace (None: the first, now)
        self._asked: float | None = None  # the earliest extra poll asked for
        self._wake = asyncio.Event()

    def ask(self, at: float) -> None:
        """A poll no later than `at` (monotonic s), besides those at the pace."""
        if self._asked is None or at < self._asked:
            self._asked = at
            self._wake.set()

    async def next_poll(self) -> None:
        """Return when the next poll is due: at the pace (the one after is set `interval`
        later, or now if this one is late), or an extra one asked for (the pace unchanged)."""
        while True:
            now = time.monotonic()
            asked = self._asked is not None and self._asked <= now
            if asked:
                self._asked = None
            if self._due is None or self._due <= now:  # at the pace
                self._due = now + self.interval if self._due is None else max(self._due + self.interval, now)
                return
            if asked:
                return
            due = self._due if self._asked is None else min(self._due, self._asked)
            self._wake.clear()
            await first_set(self._wake, timeout=due - now)


class SettleDetector:
    """True once a condition has held continuously for `hold` seconds (pure)."""

    def __init__(self, hold: float):
        if hold < 0:
            raise ValueError(f"hold {hold} s is negative")
        self.hold = float(hold)
        self._since: float | None = None

    def update(self, ok: bool, t: float) -> bool:
        """Feed one observation at time `t` (s); returns whether it has settled."""
        if not ok:
            self._since = None
            return False
        if self._since is None:
            self._since = t
        return t - self._since >= self.hold

    @property
    def settles_at(self) -> float | None:
        """When the condition, holding on, will have held `hold` s (None: not holding now)."""
        return None if self._since is None else self._since + self.hold

    def reset(self) -> None:
        self._since = None
