"""What the run engine hands to storage: one block, one point's results (SI throughout)."""

from __future__ import annotations

import threading
from collections import deque
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # the plan's types only annotate: the store does not import the run wing
    from orbitrig.run.plan import Block


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


@dataclass
class PointResults:
    tables: dict  # lms -> reduction.table.OrbitTable
    identifications: dict  # (lms, ModelSpec.key) -> {"spec": ModelSpec, "json": dict | "error": str}
    lms_comparison: dict
    truth: dict | None = None


#: CAN and drive rows kept between two journal writes (the newest; 20 min at one row per 0.5 s):
#: a run that waits for days (a confirmation, a suspend trip) neither fills the memory nor the journal
MONITOR_ROWS_KEPT = 2400


class LogBuffer:
    """Rows gathered between writes (appended to the journal with the next write); thread-safe.
    Of the CAN and drive rows only the newest MONITOR_ROWS_KEPT are kept."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._rows = self._empty()

    @staticmethod
    def _empty() -> dict[str, deque]:
        return {"events": deque(), "can": deque(maxlen=MONITOR_ROWS_KEPT), "drives": deque(maxlen=MONITOR_ROWS_KEPT)}

    def add(self, log: str, row: tuple) -> None:
        with self._lock:
            self._rows[log].append(row)

    def take(self) -> tuple[list, list, list]:
        with self._lock:
            rows, self._rows = self._rows, self._empty()
        return list(rows["events"]), list(rows["can"]), list(rows["drives"])

    def put_back(self, events: list, can: list, drives: list) -> None:
        """Return rows a failed write could not store (they go with the next write)."""
        with self._lock:
            for name, rows in (("events", events), ("can", can), ("drives", drives)):
                now = self._rows[name]
                self._rows[name] = deque([*rows, *now], maxlen=now.maxlen)  # the newest are kept
