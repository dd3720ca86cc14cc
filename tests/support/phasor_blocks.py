"""Blocks made of per-revolution phasors alone, for the orbit table's tests: the channel order, the
board's sequential slots and a BlockRecord whose counts and waveforms are zero (the table reads
only the phasors, the measured orbit speed and the coherences)."""

from __future__ import annotations

import numpy as np

from orbitrig.run.steps import Block
from orbitrig.store.records import BlockRecord

#: the eight channels' columns in a block's phasors
CH = {"fx_piezo": 0, "fy_piezo": 1, "fx_strain": 2, "fy_strain": 3, "x_a": 4, "y_a": 5, "x_b": 6, "y_b": 7}
SLOTS = np.array([np.arange(45) * 8 + k for k in range(8)])  # sequential mode: channel k at slot 8 j + k


def phasor_block(
    block: Block,
    record_phasors: np.ndarray,
    *,
    measured: float,
    coherence: np.ndarray | None = None,
    revolutions: np.ndarray | None = None,
) -> BlockRecord:
    """`block` of the per-revolution phasors `record_phasors` (N, 8), their mean its phasors, measured
    at orbit speed `measured` (rad/s); coherences zero unless given (2, 4); revolutions 0..N-1."""
    n = len(record_phasors)
    return BlockRecord(
        block=block,
        measured_orbit_speed=measured,
        raw_counts=np.zeros((n, 8, 45), np.int16),
        slots=SLOTS,
        gains=np.ones(8),
        offsets=np.zeros(8),
        mean=np.zeros((8, 45)),
        record_phasors=record_phasors,
        phasors=record_phasors.mean(axis=0),
        dc=np.zeros(8),
        rms_residual=np.zeros(8),
        coherence=np.zeros((2, 4)) if coherence is None else coherence,
        revolutions=np.arange(n) if revolutions is None else revolutions,
    )
