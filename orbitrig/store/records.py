"""What the run engine hands to storage: one block, one point's results (SI throughout)."""

from __future__ import annotations

import math
import threading
from collections import deque
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NotRequired, TypedDict

import numpy as np
import numpy.typing as npt

from orbitrig.load_systems import LoadSystem
from reduction.runout_slip import commanded_turns

if TYPE_CHECKING:  # the plan's types only annotate: the store does not import the run wing
    from orbitrig.config import ModelSpec
    from orbitrig.run.steps import Block
    from reduction.runout_slip import SpinTurns
    from reduction.table import OrbitTable
    from reduction.whirl import Directions

#: a row of the journal's event, CAN or drive log: time (s since the start) and values or texts
LogRow = tuple[float | str, ...]


@dataclass(frozen=True)
class BlockChoice:
    """Why a sequential point chose a block (or stopped): ``reason`` "next" (the next block of the
    least-time plan to the target), "target" or "cap" (the names of
    reduction.sequential.Choice, lower case), the ratio, whirl directions, revolutions and rig seconds of
    the choice, the rig seconds its blocks had spent before it, the model's coefficient names,
    and each one's predicted relative standard error (fraction of its scale) before and after."""

    reason: str
    ratio: float | None
    direction: Directions
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
    raw_counts: npt.NDArray[np.int16]  # (N, C, S)
    slots: npt.NDArray[np.integer[Any]]  # (C, S)
    gains: npt.NDArray[np.float64]  # (C,) engineering unit per count
    offsets: npt.NDArray[np.float64]  # (C,) engineering unit
    mean: npt.NDArray[np.float64]  # (C, S) engineering units
    record_phasors: npt.NDArray[np.complex128]  # (N, C)
    phasors: npt.NDArray[np.complex128]  # (C,)
    dc: npt.NDArray[np.float64]  # (C,)
    rms_residual: npt.NDArray[np.float64]  # (C,)
    coherence: npt.NDArray[np.float64]  # (2, 4) piezo|strain x (xfx, yfx, xfy, yfy)
    stats: dict[str, Any] = field(default_factory=dict)  # the averager's counters (JSON values)
    uncertainty: npt.NDArray[np.float64] | None = None  # (C,) standard uncertainty of `phasors` (N, m)
    uncertainty_turns: SpinTurns | None = None  # the spin ratio `uncertainty` took the spin tones out at
    n_records: int | None = None  # revolutions averaged (None: the rows of raw_counts)
    stop_reason: str = ""  # why averaging stopped: a daq.averaging_rule.StopReason word ("" unknown)
    revolutions: npt.NDArray[np.int64] | None = None  # (N,) the A/D board's revolution number of each record
    choice: BlockChoice | None = None  # a sequential point's reason for this block
    #: rad/s, the spin and (signed) orbit speeds as written to the drives: each REF rounded to its
    #: count (drives.rig.RigDrives.set_speeds); nan: not known (the planned speeds stand for them)
    written: tuple[float, float] = (float("nan"), float("nan"))

    def commanded_turns(self, spin: float) -> float:
        """The commanded spin turns per board revolution (reduction.runout_slip.commanded_turns):
        spin over |orbit| as written to the drives, else, when they are not known (nan: a record
        from before they were stored), ``spin`` (rad/s, the planned) over the planned |orbit|."""
        known = all(math.isfinite(v) for v in self.written)
        return commanded_turns(spin, self.block.orbit, self.written if known else None)


class IdentificationEntry(TypedDict):
    """One model identified on one load system's table: the fit's JSON object, or why it was refused."""

    spec: ModelSpec
    json: NotRequired[dict[str, Any]]
    error: NotRequired[str]


@dataclass
class PointResults:
    tables: dict[LoadSystem, OrbitTable]  # lms -> orbit table
    identifications: dict[tuple[LoadSystem, str], IdentificationEntry]  # (lms, ModelSpec.key) -> entry
    lms_comparison: dict[str, Any]  # JSON object (orbitrig.run.identification.lms_comparison)
    truth: dict[str, Any] | None = None  # JSON object (orbitrig.run.truth)
    sequential: BlockChoice | None = None  # a sequential point's last decision (target or cap)
    runout_turns: dict[str, Any] | None = None  # JSON object (orbitrig.run.identification.runout_turns)


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
    def _empty() -> dict[str, deque[LogRow]]:
        kept = {"events": EVENTS_KEPT, "can": MONITOR_ROWS_KEPT, "drives": MONITOR_ROWS_KEPT}
        return {name: deque(maxlen=n) for name, n in kept.items()}

    def add(self, log: str, row: LogRow) -> None:
        with self._lock:
            rows = self._rows[log]
            if log == "events" and len(rows) == rows.maxlen:
                self._events_left_out += 1
            rows.append(row)

    def take(self) -> tuple[list[LogRow], list[LogRow], list[LogRow]]:
        with self._lock:
            rows, self._rows = self._rows, self._empty()
            left_out, self._events_left_out = self._events_left_out, 0
        events = list(rows["events"])
        if left_out:
            t, state, _ = events[0]
            events.insert(0, (t, state, f"{left_out} earlier events left out (only the newest {EVENTS_KEPT} kept)"))
        return events, list(rows["can"]), list(rows["drives"])

    def put_back(self, events: list[LogRow], can: list[LogRow], drives: list[LogRow]) -> None:
        """Return rows a failed write could not store (they go with the next write)."""
        with self._lock:
            for name, rows in (("events", events), ("can", can), ("drives", drives)):
                now = self._rows[name]
                merged = [*rows, *now]
                if name == "events":
                    self._events_left_out += max(0, len(merged) - EVENTS_KEPT)
                self._rows[name] = deque(merged, maxlen=now.maxlen)  # the newest are kept
