"""What the run engine hands to storage: one block, one point's results (SI throughout)."""

from __future__ import annotations

import threading
from collections import deque
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # the plan's types only annotate: the store does not import the run wing
    from orbitrig.run.steps import Block


@dataclass(frozen=True)
class BlockChoice:
    """Why a sequential point chose a block (or stopped): ``reason`` "next" (the block lowering the
    largest predicted relative error most per second), "target" or "cap" (the names of
    reduction.sequential.Choice, lower case), the ratio, direction ("forward", "backward", "both"), revolutions and rig seconds of
    the choice, the rig seconds its blocks had spent before it, the model's coefficient names,
    and each one's predicted relative standard error (fraction of its scale) before and after."""

    reason: str
    ratio: float | None
    direction: str
    revolutions: int
    seconds: float
    spent_s: float
    coefficients: tuple[str, ...]
    before: tuple[float, ...]
    after: tuple[float, ...]


@dataclass
class BlockRecord:
    """Everything stored for one orbit frequency and direction."""

    block: Block
    measured_orbit_speed: float  # rad/s, |Omega| from trigger timestamps
    raw_counts: np.ndarray  # int16 (N, C, S)
    slots: np.ndarray  # (C, S)
    gains: np.ndarray  # (C,) engineering unit per count
    offsets: np.ndarray  # (C,) engineering unit
    mean: np.ndarray  # (C, S) engineering units
    record_phasors: np.ndarray  # (N, C)
    phasors: np.ndarray  # (C,)
    dc: np.ndarray  # (C,)
    rms_residual: np.ndarray  # (C,)
    coherence: np.ndarray  # (2, 4) piezo|strain x (xfx, yfx, xfy, yfy)
    stats: dict = field(default_factory=dict)
    uncertainty: np.ndarray | None = None  # (C,) standard uncertainty of `phasors` (N, m)
    n_records: int | None = None  # revolutions averaged (None: the rows of raw_counts)
    stop_reason: str = ""  # why averaging stopped: "count" | "target" | "max" ("" unknown)
    revolutions: np.ndarray | None = None  # (N,) the A/D board's revolution number of each record
    choice: BlockChoice | None = None  # a sequential point's reason for this block


@dataclass
class PointResults:
    tables: dict  # lms -> reduction.table.OrbitTable
    identifications: dict  # (lms, ModelSpec.key) -> {"spec": ModelSpec, "json": dict | "error": str}
    lms_comparison: dict
    truth: dict | None = None
    sequential: BlockChoice | None = None  # a sequential point's last decision (target or cap)


#: CAN and drive rows kept between two journal writes (the newest; 20 min at one row per 0.5 s):
#: a run that waits for days (a confirmation, a suspend trip) neither fills the memory nor the journal
MONITOR_ROWS_KEPT = 2400
#: state changes kept between two journal writes (the newest; a count stands for the rest)
EVENTS_KEPT = 500


class LogBuffer:
    """Rows gathered between writes (appended to the journal with the next write); thread-safe.
    Of the CAN and drive rows only the newest MONITOR_ROWS_KEPT are kept, of the events the
    newest EVENTS_KEPT (the first event taken then says how many were left out)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._rows = self._empty()
        self._events_left_out = 0

    @staticmethod
    def _empty() -> dict[str, deque]:
        kept = {"events": EVENTS_KEPT, "can": MONITOR_ROWS_KEPT, "drives": MONITOR_ROWS_KEPT}
        return {name: deque(maxlen=n) for name, n in kept.items()}

    def add(self, log: str, row: tuple) -> None:
        with self._lock:
            rows = self._rows[log]
            if log == "events" and len(rows) == rows.maxlen:
                self._events_left_out += 1
            rows.append(row)

    def take(self) -> tuple[list, list, list]:
        with self._lock:
            rows, self._rows = self._rows, self._empty()
            left_out, self._events_left_out = self._events_left_out, 0
        events = list(rows["events"])
        if left_out:
            t, state, _ = events[0]
            events.insert(0, (t, state, f"{left_out} earlier events left out (only the newest {EVENTS_KEPT} kept)"))
        return events, list(rows["can"]), list(rows["drives"])

    def put_back(self, events: list, can: list, drives: list) -> None:
        """Return rows a failed write could not store (they go with the next write)."""
        with self._lock:
            for name, rows in (("events", events), ("can", can), ("drives", drives)):
                now = self._rows[name]
                merged = [*rows, *now]
                if name == "events":
                    self._events_left_out += max(0, len(merged) - EVENTS_KEPT)
                self._rows[name] = deque(merged, maxlen=now.maxlen)  # the newest are kept
