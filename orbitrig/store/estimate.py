"""Bytes a run will write, to check the free space before the run and before each point.

Estimates are upper bounds of the durable pieces (orbitrig.store.pieces; measured HDF5
overhead included) with a 25 % margin; the whole-run figure adds the consolidated
run.h5, which holds a second copy of every piece. Pure arithmetic on the plan.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, Any

from orbitrig.config import RigConfig

if TYPE_CHECKING:  # annotation only: the store does not import the run wing
    from orbitrig.run.plan import OperatingPoint

MARGIN = 1.25
BLOCK_OVERHEAD = 28_672  # HDF5 superblock, object headers, attributes (units, descriptions) of one block file
RESULTS_OVERHEAD = 12_288  # results file: groups, truth and LMS comparison
PER_TABLE = 2_048  # one load system's orbit table: headers
PER_TABLE_ROW = 160  # orbit (2 x 8), 4 complex phasors (64), gamma2 (32), n_records, u (40)
PER_IDENTIFICATION = 20_480  # one model on one table: JSON, names, covariance, intervals, budget, derived groups
POINT_FIXED = 8_192  # point.json, commit record, journal lines, the CSV rows
N_LMS = 2


def samples_per_channel(rig: RigConfig) -> int:
    """Samples of each channel in one orbit revolution (360 slots shared in sequential mode)."""
    n = len(rig.channels)
    return 360 // n if rig.transports.adc_mode == "sequential" else 360


def block_bytes(rig: RigConfig, revolutions: int) -> int:
    """One stored orbit frequency of `revolutions` revolutions (before the margin)."""
    c, s = len(rig.channels), samples_per_channel(rig)
    raw = revolutions * c * s * 2  # int16 counts
    per_rev = revolutions * c * 16  # complex phasor of every revolution
    per_sample = c * s * (2 + 8)  # slots (int16), synchronous mean (float64)
    per_channel = c * (8 * 5 + 16)  # gains, offsets, dc, rms residual, uncertainty; phasors
    return raw + per_rev + per_sample + per_channel + 64 + BLOCK_OVERHEAD


def results_bytes(n_blocks: int, n_models: int) -> int:
    """A point's results file: orbit tables of both load systems and every identification."""
    return RESULTS_OVERHEAD + N_LMS * (PER_TABLE + n_blocks * PER_TABLE_ROW + n_models * PER_IDENTIFICATION)


def point_bytes(rig: RigConfig, point: OperatingPoint, revolutions: int | Sequence[int], n_models: int = 8) -> int:
    """Everything one operating point writes (margin included); `revolutions`: the most every
    block averages, or one count per block."""
    n = len(point.blocks)
    counts = [revolutions] * n if isinstance(revolutions, int) else list(revolutions)
    raw = sum(block_bytes(rig, r) for r in counts) + results_bytes(n, n_models) + POINT_FIXED
    return int(raw * MARGIN)


def plan_bytes(rig: RigConfig, steps: Iterable[Any]) -> int:
    """Everything the plan `steps` writes: every point's pieces, then run.h5 (a second copy).
    Of the steps (orbitrig.run.plan) the acquisitions (a ``revolutions`` count) and the
    identifications (``models``) of a point count."""
    blocks: dict[int, list[int]] = {}
    models: dict[int, int] = {}
    for s in steps:
        if s.point is None:
            continue
        if hasattr(s, "revolutions"):
            blocks.setdefault(s.point, []).append(s.revolutions)
        elif hasattr(s, "models"):
            models[s.point] = len(s.models)
    pieces = 0
    for p, revs in blocks.items():
        pieces += sum(block_bytes(rig, r) for r in revs) + results_bytes(len(revs), models.get(p, 8)) + POINT_FIXED
    return int(2 * pieces * MARGIN) + 65_536  # + run.json, journal, coefficients.csv
