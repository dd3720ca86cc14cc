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
