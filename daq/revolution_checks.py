"""The checks behind a dropped revolution (daq.revolutions): did the board clock advance steadily
over a revolution (a stalled or jumping clock gives no true period: ``bad_clock``), and why a frame
does not continue the one before it (the drop reason counted in daq.stats). Pure.
"""

from __future__ import annotations

import numpy as np

from daq.adc_mode import SLOTS_PER_REV
from daq.frames import FrameBatch


def steady_clock(
    dt_frame: np.ndarray,
    n_slots: np.ndarray,
    first: np.ndarray,
    last: np.ndarray,
    period_us: np.ndarray,
    rel_tol: float = 0.05,
    abs_tol_us: float = 2.0,
) -> np.ndarray:
    """For each revolution (frames first..last, then the next trigger at last+1):
    did the board clock advance steadily, each frame's step within ``rel_tol``
    (+ ``abs_tol_us`` for the clock's 1 us rounding) of its slots' share of the
    period? A stalled or jumping clock fails (its period would be wrong)."""
    stop = np.minimum(last + 1, len(dt_frame) - 1)  # steps first+1 .. stop (>= 1: a revolution has >= 2 frames)
    lengths = stop - first
    if not len(lengths):
        return np.ones(0, bool)
    offsets = np.cumsum(lengths) - lengths
    step = np.repeat(first + 1 - offsets, lengths) + np.arange(int(lengths.sum()))
    expected = n_slots[step - 1] * np.repeat(period_us / SLOTS_PER_REV, lengths)
    bad = np.abs(dt_frame[step] - expected) > rel_tol * expected + abs_tol_us
    steady: np.ndarray = np.add.reduceat(bad, offsets) == 0
    return steady


class BreakReasons:
    """Why frame i does not continue frame i-1 (a drop reason)."""

    def __init__(
        self,
        b: FrameBatch,
        trig: np.ndarray,
        overrun: np.ndarray,
        mode_ok: np.ndarray,
        seq_ok: np.ndarray,
        prev_rev: np.ndarray,
        clock_ok: np.ndarray,
    ) -> None:
        self.b, self.trig, self.overrun, self.mode_ok = b, trig, overrun, mode_ok
        self.seq_ok, self.prev_rev, self.clock_ok = seq_ok, prev_rev, clock_ok

    def __call__(self, i: int) -> str:
        if not self.seq_ok[i]:
            return "corrupt" if self.b.skipped_before[i] else "seq_gap"
        if self.overrun[i]:
            return "overrun"
        if not self.mode_ok[i]:
            return "mode_mismatch"
        if not self.clock_ok[i]:
            return "bad_clock"
        if self.trig[i]:
            return "incomplete"
        if self.b.rev[i] != self.prev_rev[i]:
            return "rev_mismatch"
        return "slot_gap"
