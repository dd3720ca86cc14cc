"""What the run engine tells its subscribers (terminal UI, MQTT) and returns.

A note of the run (a line of run.log and of run.h5's events that is no state change) reaches the
subscribers as a `NoteEvent` with its `Severity`: routine (speeds set, a pause requested) or a
warning, something gone wrong that the run survived (an A/D link drop, an acquisition failed and
retried, a suspension's new cause); `orbitrig sweep`'s console shows the warnings, `orbitrig serve`
publishes them on ``<prefix>/note``."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path
from typing import Any, Callable, Protocol

from orbitrig.errors import OrbitrigError
from orbitrig.run.states import Outcome, RunState


@dataclass(frozen=True)
class StatusEvent:
    state: RunState
    run_id: str | None
    since: str  # ISO-8601
    message: str = ""
    #: the operating point under way (OperatingPoint.label); between points (`between_points`) the next
    #: one while paused before it or resuming; None between runs, during the closing ramp and a stop between points
    point_label: str | None = None
    between_points: bool = False


@dataclass(frozen=True)
class ProgressEvent:
    run_id: str | None
    point: int  # 1-based count of the run's points (a resume's: those measured before it included)
    points: int  # the run's points (a resume's: all of its matrix, not those left)
    frequency: int  # 1-based count of blocks (frequency x direction) in the point
    frequencies: int
    revolutions: int  # good revolutions so far in the current block
    eta_s: float | None  # wall seconds
    point_label: str | None = None  # the point's OperatingPoint.label (w1000rpm_pr0.4826MPa_...)
    block_revolutions: int = 0  # the block's target: its revolutions (adaptive: the most), 0 before the first block
    acquired: bool = False  # the block under way has its revolutions (its acquisition is done)
    before: int = 0  # the run's points measured before a resume (counted in ``point``)

    @property
    def blocks_done(self) -> int:
        """Blocks of the point acquired: those before the block under way, and it once acquired."""
        return max(0, self.frequency - (0 if self.acquired else 1))

    @property
    def fraction(self) -> float:
        """How much of the run's points is measured (0 to 1), the one count the terminal and the page
        show: the points before this one, and of this one its blocks acquired and the block under
        way's revolutions of its target (point 1 of 3 with its last block acquired: 1/3)."""
        if self.points <= 0:
            return 0.0
        under_way = 0.0
        if not self.acquired and self.block_revolutions > 0 and self.frequency > 0:
            under_way = min(1.0, self.revolutions / self.block_revolutions)
        of_point = (self.blocks_done + under_way) / self.frequencies if self.frequencies > 0 else 0.0
        return min(1.0, (max(0, self.point - 1) + min(1.0, of_point)) / self.points)


@dataclass(frozen=True)
class ResultEvent:
    run_id: str | None
    payload: dict[str, Any]


class Severity(StrEnum):
    """How much a note of the run matters to the operator watching it."""

    INFO = "info"  # routine: speeds set, drives ramped to zero, a pause requested
    WARNING = "warning"  # something gone wrong that the run survived (once per block at most)


class NoteKind(StrEnum):
    """What a warning of the run is about, in the words a supervisor reads (counted by kind when
    warnings are withheld, docs/protocols/mqtt.md)."""

    ADC_LINK_DROP = "A/D link drop"
    ACQUISITION_RETRIED = "acquisition retried"
    INTERLOCK_CHANGED = "interlock cause changed"
    DISK_FULL = "disk still full"
    STORAGE_WAIT = "storage waited for"
    LIVE_FEED_DETACHED = "live feed detached"
    STORAGE = "storage warning"  # the store's own: a journal.jsonl deleted during the run
    OTHER = "other"


@dataclass(frozen=True)
class NoteEvent:
    run_id: str | None
    severity: Severity
    message: str
    kind: NoteKind = NoteKind.OTHER


class Note(Protocol):
    """Where the run's parts say a note (run.log, run.h5's events, the subscribers)."""

    def __call__(self, message: str, severity: Severity = Severity.INFO, kind: NoteKind = NoteKind.OTHER) -> None: ...


Event = StatusEvent | ProgressEvent | ResultEvent | NoteEvent
Subscriber = Callable[[Event], None]


@dataclass
class RunOutcome:
    status: Outcome
    message: str
    run_id: str
    out_dir: Path
    completed_points: list[int] = field(default_factory=list)
    points: int = 0


class RunFailed(OrbitrigError):
    """The run cannot go on (interlock, verification, hardware, storage)."""
