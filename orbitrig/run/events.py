"""What the run engine tells its subscribers (terminal UI, MQTT) and returns."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from orbitrig.errors import OrbitrigError
from orbitrig.run.states import Outcome, RunState


@dataclass(frozen=True)
class StatusEvent:
    state: RunState
    run_id: str | None
    since: str  # ISO-8601
    message: str = ""


@dataclass(frozen=True)
class ProgressEvent:
    run_id: str | None
    point: int  # 1-based count of points in this run
    points: int
    frequency: int  # 1-based count of blocks (frequency x direction) in the point
    frequencies: int
    revolutions: int  # good revolutions so far in the current block
    eta_s: float | None  # wall seconds


@dataclass(frozen=True)
class ResultEvent:
    run_id: str | None
    payload: dict[str, Any]


Event = StatusEvent | ProgressEvent | ResultEvent
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
