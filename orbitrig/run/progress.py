"""Progress of a run for its subscribers: point, block, revolutions, ETA (wall s).

Revolutions are throttled (at most one event per `every` s); a block's start (with its target
revolutions), its end (its final revolution count, `acquired`: sent as its acquisition is done)
and a point's start (frequency and revolutions 0 until its first block) are always sent. How much
of the run is measured is the event's `fraction` (orbitrig.run.events.ProgressEvent), which the
terminal's bars and the dashboard (the progress payload's ``fraction``) show.
"""

from __future__ import annotations

import time
from typing import Callable

from orbitrig.run.events import ProgressEvent
from orbitrig.run.rig_io import TimeScale
from orbitrig.run.states import RunState

#: why the ETA stands still, by the state that holds the run (the terminal's bars and the dashboard
#: say it after the ETA; the plan's rig time left does not run down in these states)
ETA_HELD = {RunState.WAITING: "paused: waiting for the operator", RunState.PAUSED: "paused with the run"}


class ProgressMeter:
    """Counts what is done and estimates what is left (physical s, shown as wall s)."""

    def __init__(self, emit: Callable[[ProgressEvent], None], scale: TimeScale, *, every: float = 0.1):
        self._emit = emit
        self.scale = scale
        self.every = every  # s between two revolution events, at most one per interval
        self.run_id: str | None = None
        self.point = self.points = self.frequency = self.frequencies = self.revolutions = 0
        self.before = 0  # points of the run measured before a resume
        self.target = 0  # the block's revolutions (Acquire.revolutions), 0 before the point's first block
        self.acquired = False  # the block under way has its revolutions
        self.remaining = 0.0
        self.label: str | None = None  # the operating point under way (OperatingPoint.label)
        self._last = 0.0
        self._unsent = False  # a revolution counted and not yet sent (throttled)

    def start(self, run_id: str, points: int, remaining: float, before: int = 0) -> None:
        """A run of ``points`` starts (``remaining``: physical s of its plan left); ``before`` of them
        were measured before a resume: points are counted as the whole run's (the next one is
        ``before`` + 1 of ``points``), so a resume's bar and ``fraction`` start where the run stood."""
        self.run_id, self.points, self.remaining, self.before = run_id, points, remaining, before
        self.point, self.frequency = before, 0
        self.frequencies = self.revolutions = self.target = 0
        self.label, self.acquired = None, False

    def next_point(self, frequencies: int, label: str) -> None:
        """A point (its OperatingPoint.label) starts: sent at once (no block acquired yet)."""
        self.point, self.label = self.point + 1, label
        self.frequency, self.frequencies, self.revolutions, self.target = 0, frequencies, 0, 0
        self.acquired = False
        self.emit(force=True)

    def block(self, frequency: int, revolutions: int) -> None:
        """A block (1-based in the point) starts acquiring its `revolutions` (again after a failed attempt)."""
        self.frequency, self.revolutions, self.target, self.acquired = frequency, 0, revolutions, False
        self.emit(force=True)

    def block_acquired(self) -> None:
        """The block's acquisition is done: its final count goes out, the block counted as measured."""
        self.acquired = True
        self.emit(force=True)

    def revolution(self) -> None:
        self.revolutions += 1
        self.emit()

    def spent(self, physical_s: float) -> None:
        """A step is done: the count it left unsent (a block's last revolutions) goes out now."""
        self.remaining -= physical_s
        if self._unsent:
            self.emit(force=True)

    def emit(self, force: bool = False) -> None:
        now = time.monotonic()
        if not force and now - self._last < self.every:
            self._unsent = True
            return
        self._last, self._unsent = now, False
        eta = self.scale.wall(max(0.0, self.remaining))
        self._emit(
            ProgressEvent(
                self.run_id,
                self.point,
                self.points,
                self.frequency,
                self.frequencies,
                self.revolutions,
                round(eta, 1),
                self.label,
                self.target,
                self.acquired,
                self.before,
            )
        )
