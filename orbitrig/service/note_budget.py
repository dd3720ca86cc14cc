"""How many of the run's warnings the rig service publishes on ``<prefix>/note``: at most
``BURST`` in any ``WINDOW_S`` s. The engine says a warning at most once per block, but a run of
short blocks (or a speed-up) could say many; each one is a QoS 1 message that the broker queues for
every subscriber whose link is down (a dashboard's session: up to ``max_queued_messages`` per
client, beyond which mosquitto drops messages silently). At 10 a minute a dashboard's 600 s
catch-up (its session expiry) holds at most 100 of them. A warning beyond the budget is not published (run.log and
run.h5 keep it); the next one published says how many were withheld before it."""

from __future__ import annotations

import collections
import time
from collections.abc import Callable

BURST = 10  # warnings published at most in any WINDOW_S
WINDOW_S = 60.0  # s


class NoteBudget:
    """The sliding window of the warnings published (``clock``: s, monotonic)."""

    def __init__(self, burst: int = BURST, window_s: float = WINDOW_S, clock: Callable[[], float] = time.monotonic):
        self.burst, self.window_s, self._clock = burst, window_s, clock
        self._sent: collections.deque[float] = collections.deque()
        self.withheld = 0  # warnings not published since the last one that was

    def admit(self) -> int | None:
        """None when the next warning is over the budget (counted as withheld); else how many were
        withheld before it (then reset)."""
        now = self._clock()
        while self._sent and now - self._sent[0] >= self.window_s:
            self._sent.popleft()
        if len(self._sent) >= self.burst:
            self.withheld += 1
            return None
        self._sent.append(now)
        withheld, self.withheld = self.withheld, 0
        return withheld
