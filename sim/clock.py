"""Simulated time: physics and the A/D board clock run `speedup` times wall time."""

from __future__ import annotations

import time


class SimClock:
    """Monotonic simulated clock.

    ``now()`` returns simulated seconds since the clock was created,
    ``(time.monotonic() - t0) * speedup``. The speed-up may be changed while
    running; simulated time stays continuous.
    """

    def __init__(self, speedup: float = 1.0, *, wall=time.monotonic):
        if not speedup > 0:
            raise ValueError(f"speedup must be > 0, got {speedup!r}")
        self._wall = wall
        self._speedup = float(speedup)
        self._wall_ref = wall()
        self._sim_ref = 0.0

    @property
    def speedup(self) -> float:
        return self._speedup

    @speedup.setter
    def speedup(self, value: float) -> None:
        if not value > 0:
            raise ValueError(f"speedup must be > 0, got {value!r}")
        self._sim_ref = self.now()
        self._wall_ref = self._wall()
        self._speedup = float(value)

    def now(self) -> float:
        """Simulated time in seconds."""
        return self._sim_ref + (self._wall() - self._wall_ref) * self._speedup

    __call__ = now


class AwakeClock:
    """Wall time (s, monotonic) without this simulator process's own stalls.

    The simulated drives' comm-loss watchdog runs on it. A real drive is a machine of
    its own and is never late; this process can be (other processes take the CPU, its
    worker thread holds the interpreter lock), and a request that waited in its socket
    while it stood still must not count as a request that came late. A task calls
    ``tick()`` every few ms; time beyond ``grace`` s between two ticks (also while the
    next tick is overdue) was a stall and does not count. When the master is silent
    and this process runs, the clock runs with wall time: the watchdog trips as it should.
    """

    def __init__(self, grace: float = 0.1, *, wall=time.monotonic):
        self._wall, self.grace = wall, grace
        self._last = wall()
        self.stalled = 0.0  # s not counted so far

    def tick(self) -> None:
        t = self._wall()
        self.stalled += max(0.0, t - self._last - self.grace)
        self._last = t

    def __call__(self) -> float:
        t = self._wall()
        return t - self.stalled - max(0.0, t - self._last - self.grace)
