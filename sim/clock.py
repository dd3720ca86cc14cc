"""Simulated time: physics and the A/D board clock run `speedup` times wall time (slower when the
simulator cannot keep up: SimClock.hold)."""

from __future__ import annotations

import math
import threading
import time


class SimClock:
    """Monotonic simulated clock.

    ``now()`` returns simulated seconds since the clock was created,
    ``(time.monotonic() - t0) * speedup``. The speed-up may be changed while
    running; simulated time stays continuous.

    ``hold(limit)``: the clock does not pass ``limit`` (simulated s). Standing there, simulated
    time does not run (``lost`` counts the simulated s it would have run); it runs on from there
    at ``speedup`` once the limit is raised. The A/D board holds it a short lead ahead of its
    last conversion (sim.slot_stream), so a simulator that cannot keep up slows its own time
    instead of letting the board trail the drives.
    """

    def __init__(self, speedup: float = 1.0, *, wall=time.monotonic):
        if not speedup > 0:
            raise ValueError(f"speedup must be > 0, got {speedup!r}")
        self._wall = wall
        self._speedup = float(speedup)
        self._wall_ref = wall()
        self._sim_ref = 0.0
        self._limit = math.inf
        self._lock = threading.Lock()  # the truth's requests may read it from a worker thread
        self.lost = 0.0  # simulated s not run while held

    @property
    def speedup(self) -> float:
        return self._speedup

    @speedup.setter
    def speedup(self, value: float) -> None:
        if not value > 0:
            raise ValueError(f"speedup must be > 0, got {value!r}")
        with self._lock:
            self._sim_ref = self._now()
            self._wall_ref = self._wall()
            self._speedup = float(value)

    def hold(self, limit: float) -> None:
        """From now on the clock does not pass ``limit`` (simulated s; inf: it runs free)."""
        with self._lock:
            self._now()  # held at the old limit up to now
            self._limit = float(limit)

    def now(self) -> float:
        """Simulated time in seconds."""
        with self._lock:
            return self._now()

    def _now(self) -> float:
        wall = self._wall()
        t = self._sim_ref + (wall - self._wall_ref) * self._speedup
        if t <= self._limit:
            return t
        held = max(self._limit, self._sim_ref)  # a limit lowered below the time reached: it stands
        self.lost += t - held
        self._sim_ref, self._wall_ref = held, wall
        return held

    __call__ = now


class AwakeClock:
    """Wall time (s, monotonic) without this simulator process's own stalls.

    The simulated drives' comm-loss watchdog runs on it. A real drive is a machine of
    its own and is never late; this process can be (other processes take the CPU, its
    worker thread holds the interpreter lock, a test blocks the loop that serves the
    drives), and a request that waited in its socket while it stood still must not count
    as a request that came late. The loop serving the drives calls ``tick()`` every few
    ms (sim/modbus_server.py); time beyond ``grace`` s between two ticks (also while the
    next tick is overdue) was a stall and does not count. When the master is silent
    and this process runs, the clock runs with wall time: the watchdog trips as it
    should. Before the first tick and after ``unwatched()`` nobody measures stalls and
    every wall second counts.
    """

    def __init__(self, grace: float = 0.1, *, wall=time.monotonic):
        self._wall, self.grace = wall, grace
        self._last: float | None = None  # the last tick (s wall); None: no loop ticks it
        self.stalled = 0.0  # s not counted so far

    def tick(self) -> None:
        """The loop serving the drives runs now."""
        t = self._wall()
        if self._last is not None:
            self.stalled += max(0.0, t - self._last - self.grace)
        self._last = t

    def unwatched(self) -> None:
        """The loop stops ticking (its server closed): the stall so far is counted out, and
        from now on every wall second counts."""
        if self._last is not None:
            self.tick()
        self._last = None

    def wall(self) -> float:
        """Wall time (s), the stalls included."""
        return self._wall()

    def __call__(self) -> float:
        t = self._wall()
        overdue = 0.0 if self._last is None else max(0.0, t - self._last - self.grace)
        return t - self.stalled - overdue
