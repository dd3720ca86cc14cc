"""Is there room on the disk for what the plan will write? Estimates in bytes.

The engine asks before the run and before each operating point; too little
room pauses the run (nothing is lost, the operator frees space and resumes).
"""

from __future__ import annotations

import shutil
from pathlib import Path

#: bytes per revolution and channel beyond the raw counts (per-record phasors, logs)
_PER_RECORD_CHANNEL = 32
#: bytes per block beyond its arrays (HDF5 groups, attributes, orbit table rows)
_PER_BLOCK = 64 * 1024
#: bytes per point beyond its blocks (identifications, truth, CSV rows)
_PER_POINT = 256 * 1024
#: margin kept free besides the estimate
MARGIN_BYTES = 16 * 1024 * 1024


def point_bytes(n_blocks: int, revolutions: int, channels: int, slots: int) -> int:
    """Bytes one operating point adds to the run directory (raw counts int16, averages float64)."""
    raw = revolutions * channels * slots * 2
    per_block = raw + channels * slots * 8 * 3 + revolutions * channels * _PER_RECORD_CHANNEL + _PER_BLOCK
    return n_blocks * per_block + _PER_POINT


def room_problem(directory: Path, n_bytes: int) -> str | None:
    """Why `directory` cannot take `n_bytes` more (plus a margin), or None if it can."""
    free = shutil.disk_usage(directory).free
    need = n_bytes + MARGIN_BYTES
    if free >= need:
        return None
    return (f"not enough free disk space in {directory}: {free / 1e6:.1f} MB free, "
            f"{need / 1e6:.1f} MB needed for the next point")  # fmt: skip
