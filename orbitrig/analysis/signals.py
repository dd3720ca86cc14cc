"""The stored signals of one orbit frequency (block), for the report's signal figures.

A block holds the synchronous average of N revolutions (``mean``, engineering units,
one row per channel at that channel's slots) and the raw A/D counts of every
revolution (``raw_counts``; engineering value = gain * count + offset). The report
reads the average and ONE raw revolution (a slice, not the whole block), in either
storage layout: a block file ``points/PPPP/FF_dir.h5`` (its root is the block) or the
group ``/points/PPPP/frequencies/FF_dir`` of ``run.h5``.

Orbit angle theta = 2 pi slot / 360 (rad after the once-per-orbit trigger); phasors
follow q(theta) = dc + Re(q_bar e^{i theta}).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from daq.frames import slot_angle
from orbitrig.config import LMS
from orbitrig.store.layout import RunLayout
from orbitrig.store.reader import RunDirError, stored_channels
from orbitrig.store.stored_run import Frequency, Point, Run

#: force channels per load measuring system and probe channels per plane
FORCE_CHANNELS = {lms: (f"fx_{lms}", f"fy_{lms}") for lms in LMS}
PROBE_PLANES = {"A": ("x_a", "y_a"), "B": ("x_b", "y_b")}


@dataclass(frozen=True)
class BlockSignals:
    """One block's average and one raw revolution (SI: N, m), per channel name."""

    frequency: Frequency
    channels: dict[str, int]  # channel name -> row
    theta: np.ndarray  # (C, S) rad, orbit angle of each sample
    mean: np.ndarray  # (C, S) synchronous average of the block
    raw: np.ndarray  # (C, S) the revolution `revolution`, gain * counts + offset
    revolution: int  # which stored revolution `raw` is (0 = first)
    n_revolutions: int

    def of(self, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(theta in deg sorted ascending, average, raw revolution) of channel `name`."""
        i = self.channels[name]
        order = np.argsort(self.theta[i])
        return np.degrees(self.theta[i][order]), self.mean[i][order], self.raw[i][order]


def channel_map(run: Run) -> dict[str, int]:
    """Channel name -> row of the stored arrays: the run's channel list, else (older runs) the
    rig configuration stored in the run with the calibration record stored beside it."""
    names, _ = stored_channels(run)
    return {name: i for i, name in enumerate(names)}


def _open_block(run: Run, point: Point, frequency: Frequency):
    """(h5py file, group) of the block, in the pieces layout or in run.h5."""
    import h5py

    layout = RunLayout(run.directory)
    piece = layout.block_file(point.index, frequency.name)
    path = piece if piece.is_file() else layout.run_file
    try:
        h5 = h5py.File(path, "r")
    except OSError as err:
        raise RunDirError(path, f"cannot read block {frequency.name} ({err})") from err
    if path == piece:
        return h5, h5
    key = f"points/{point.name}/frequencies/{frequency.name}"
    if key not in h5:
        h5.close()
        raise RunDirError(path, f"no group {key}")
    return h5, h5[key]


def read_block_signals(run: Run, point: Point, frequency: Frequency, revolution: int = 0) -> BlockSignals:
    """The average and the raw revolution `revolution` of one stored block."""
    channels = channel_map(run)
    h5, g = _open_block(run, point, frequency)
    with h5:
        try:
            slots = np.asarray(g["slots"][()], dtype=float)
            mean = np.asarray(g["mean"][()], dtype=float)
            counts = g["raw_counts"]
            n = int(counts.shape[0])
            if n == 0:
                raise ValueError("no revolution stored")
            k = min(max(revolution, 0), n - 1)
            raw = np.asarray(counts[k], dtype=float) * np.asarray(g["gains"][()], dtype=float)[:, None]
            raw += np.asarray(g["offsets"][()], dtype=float)[:, None]
        except (KeyError, ValueError, TypeError, OSError) as err:
            raise RunDirError(Path(h5.filename), f"block {point.name}/{frequency.name}: {err}") from err
    if mean.shape != slots.shape or raw.shape != mean.shape:
        raise RunDirError(
            run.directory,
            f"block {point.name}/{frequency.name}: mean {mean.shape}, "
            f"slots {slots.shape}, raw revolution {raw.shape} differ",
        )
    return BlockSignals(frequency, channels, slot_angle(slots), mean, raw, k, n)


def default_frequencies(point: Point) -> list[Frequency]:
    """The report's default subset: the lowest and highest orbit frequency of each whirl direction."""
    chosen: list[Frequency] = []
    for direction in (1, -1):
        blocks = sorted(
            (f for f in point.frequencies if f.direction == direction and f.complete), key=lambda f: f.orbit_hz
        )
        for f in blocks[:1] + blocks[-1:]:
            if f not in chosen:
                chosen.append(f)
    return chosen
