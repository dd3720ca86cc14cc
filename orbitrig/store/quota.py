"""How much a run's logs may grow between two completed points.

Between two completed points (or before the first, or after the last) a run can
wait for a long time: for a confirmation, a suspend trip that clears and trips
again, an operator who pauses and resumes. Its logs must not grow with that time.
Of the lines offered to a log in such an interval a `LineQuota` lets the first
`head` through at once, holds the newest `tail` in memory and counts the rest;
`close` (when a point completes or the run ends) returns the count and the held
lines, which the writer then appends after a line saying what was left out. A log
therefore grows by at most head + tail + 1 lines per interval.
"""

from __future__ import annotations

import threading
from collections import deque
from dataclasses import dataclass

RUN_LOG_HEAD, RUN_LOG_TAIL = 2000, 50  # run.log lines per interval (a point writes about 40)
COMMANDS_HEAD, COMMANDS_TAIL = 100, 20  # journal `command` lines per interval


@dataclass(frozen=True)
class LeftOut:
    """What `LineQuota.close` hands back: the count left out and the newest lines held."""

    count: int
    tail: list[str]


class LineQuota:
    """The first `head` lines pass, the newest `tail` are held, the rest counted (thread-safe)."""

    def __init__(self, head: int, tail: int):
        self.head = head
        self._lock = threading.Lock()
        self._passed = 0
        self._held: deque[str] = deque(maxlen=tail)
        self._dropped = 0

    def offer(self, line: str) -> bool:
        """True: write `line` now; False: it is held (or counted) until `close`."""
        with self._lock:
            if self._passed < self.head:
                self._passed += 1
                return True
            if len(self._held) == self._held.maxlen:
                self._dropped += 1
            self._held.append(line)
            return False

    def close(self) -> LeftOut:
        """End the interval: the count of lines left out and the held lines, oldest first."""
        with self._lock:
            out = LeftOut(self._dropped, list(self._held))
            self._passed, self._dropped = 0, 0
            self._held.clear()
        return out
