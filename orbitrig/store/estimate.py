"""Bytes a run will write, to check the free space before the run and before each point.

Estimates are upper bounds of the durable pieces (orbitrig.store.pieces; HDF5 overhead
measured on stored runs, a simulated run's truth fits included) with a 25 % margin. A point
also adds its copy to the run.h5 under construction as it completes, so the figure of a
point, like that of the whole run, counts every piece twice. Arithmetic on the plan, and on
the files stored for the end of a run (`final_bytes`).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from daq.adc_mode import SLOTS_PER_REV, AdcMode
from orbitrig.config import RigConfig
from orbitrig.store.layout import RunLayout

if TYPE_CHECKING:  # annotation only: the store does not import the run wing
    from orbitrig.run.plan import OperatingPoint

MARGIN = 1.25
BLOCK_OVERHEAD = 28_672  # HDF5 superblock, object headers, attributes (units, descriptions) of one block file
# results.h5, measured: about 14 kB + 4.3 kB per block + 54 kB (kc8) to 78 kB (power-law fits)
# per identification; the attributes (units, descriptions) of its ~40 datasets dominate
RESULTS_OVERHEAD = 20_480  # results file: groups, truth (simulated runs) and LMS comparison
PER_TABLE = 2_048  # one load system's orbit table: headers
PER_TABLE_ROW = 2_560  # one block's table row of one load system, with its share of the truth fits
PER_IDENTIFICATION = 65_536  # one model on one table (kc8 54 kB; power-law fits, up to 78 kB, within the margin)
POINT_FIXED = 8_192  # point.json, commit record, journal lines, the CSV rows
N_LMS = 2
FINAL_FIXED = 65_536  # run.h5's root attributes, channel lists and the logs' HDF5 overhead


def samples_per_channel(rig: RigConfig) -> int:
    """Samples of each channel in one orbit revolution (360 slots shared in sequential mode)."""
    n = len(rig.channels)
    return SLOTS_PER_REV // n if rig.transports.adc_mode is AdcMode.SEQUENTIAL else SLOTS_PER_REV


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
    """The durable pieces of one operating point (margin included); `revolutions`: the most
    every block averages, or one count per block."""
    n = len(point.blocks)
    counts = [revolutions] * n if isinstance(revolutions, int) else list(revolutions)
    raw = sum(block_bytes(rig, r) for r in counts) + results_bytes(n, n_models) + POINT_FIXED
    return int(raw * MARGIN)


def point_room(rig: RigConfig, point: OperatingPoint, revolutions: int | Sequence[int], n_models: int = 8) -> int:
    """Everything one operating point writes: its pieces, then their copy into the run.h5
    under construction when it completes (margin included)."""
    return 2 * point_bytes(rig, point, revolutions, n_models)


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


def final_bytes(layout: RunLayout, not_copied: Iterable[int]) -> int:
    """Bytes the consolidation of run.h5 still adds when the run ends (an estimate; a disk that
    fills up anyway gives a StorageFullError): the header and the logs, about as large as
    run.json and the journal, and the copy of each complete point `not_copied` into it yet."""
    left = 0
    for i in not_copied:
        try:
            left += sum(_size(p) for p in layout.point_dir(i).iterdir())
        except OSError:
            pass  # a point that cannot be listed cannot be copied either
    return 2 * (_size(layout.header) + _size(layout.journal)) + left + FINAL_FIXED


def _size(path: Path) -> int:
    try:
        return path.stat().st_size
    except OSError:
        return 0
