"""Rig time of orbit blocks: the one estimator the plan, the design, the dry run and the bench use.

A block at orbit speed Omega averaging n revolutions takes (n + 1) orbit periods 2 pi / |Omega|:
the extra one finds the trigger before the first whole revolution. A list of orbit ratios
r = |Omega| / omega at spin omega is run in one or both whirl directions (two blocks per
ratio for both directions), or each ratio in its own (``directions`` one per ratio: a ratio may
then be there twice, once forward and once backward); per block a fixed overhead (settle hold
and store) is added, and per point the orbit drive's ramps: forward from the highest forward
|Omega| down, backward back up to the highest backward |Omega| (2 x the highest |Omega| for
both directions, once for one). Seconds, physical.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import overload

import numpy as np
from numpy.typing import ArrayLike

from reduction.whirl import Directions, Whirl

#: the whirl directions of a list: one for every ratio, or one per ratio
Ways = Directions | Sequence[Directions]

TRIGGER_REVOLUTIONS = 1  # revolutions spent finding the trigger before a block's first whole one


def blocks_per_ratio(size: int, directions: Ways) -> np.ndarray:
    """(size,) blocks of each ratio: 2 for both directions, else 1 (``directions`` one for all or one per ratio)."""
    ways = [directions] * size if isinstance(directions, str) else list(directions)
    if len(ways) != size:
        raise ValueError(f"{len(ways)} directions for {size} ratios: give one for all or one per ratio")
    return np.array([Directions(w).blocks for w in ways], dtype=float)


def revolution_time(ratios: ArrayLike, spin: float, directions: Ways = Directions.BOTH) -> np.ndarray:
    """(k,) seconds of one revolution at each ratio, 2 pi / (r omega), summed over its whirl
    directions (two blocks per ratio for both)."""
    r = np.asarray(ratios, dtype=float)
    t: np.ndarray = blocks_per_ratio(r.size, directions) * 2 * np.pi / (r * spin)
    return t


@overload
def block_time(orbit: float, revolutions: float) -> float: ...


@overload
def block_time(orbit: np.ndarray, revolutions: ArrayLike) -> np.ndarray: ...


def block_time(orbit: float | np.ndarray, revolutions: ArrayLike) -> float | np.ndarray:
    """Seconds of one block (or an array of blocks): (revolutions + 1) x 2 pi / |orbit|
    (orbit rad/s, signed or not)."""
    n = np.asarray(revolutions, dtype=float) + TRIGGER_REVOLUTIONS
    t: np.ndarray = n * 2 * np.pi / np.abs(np.asarray(orbit, dtype=float))
    return float(t) if np.ndim(t) == 0 else t


def list_time(ratios: ArrayLike, spin: float, revolutions: ArrayLike, directions: Ways = Directions.BOTH) -> float:
    """Seconds averaging the blocks of ``ratios`` (each ratio's ``revolutions``, one count or one
    per ratio, in every one of its directions), trigger revolutions included."""
    r = np.asarray(ratios, dtype=float)
    n = np.broadcast_to(np.asarray(revolutions, dtype=float), r.shape)
    return float(np.sum(blocks_per_ratio(r.size, directions) * block_time(r * spin, n)))


def point_time(
    ratios: ArrayLike,
    spin: float,
    revolutions: ArrayLike,
    directions: Ways = Directions.BOTH,
    *,
    per_block_s: float = 0.0,
    ramp_rate: float | None = None,
) -> float:
    """Seconds of a point's blocks: :func:`list_time` + blocks x ``per_block_s`` (settle hold,
    store) + the orbit ramps at ``ramp_rate`` (rad/s per s; None: left out)."""
    r = np.asarray(ratios, dtype=float)
    ways = [directions] * r.size if isinstance(directions, str) else list(directions)
    blocks = float(np.sum(blocks_per_ratio(r.size, ways)))
    top = [max((x for x, w in zip(r, ways) if v in Directions(w).whirls), default=0.0) for v in Whirl]
    ramps = 0.0 if ramp_rate is None else float(sum(top)) * spin / ramp_rate
    return list_time(r, spin, revolutions, ways) + blocks * per_block_s + ramps
