"""Rig time of orbit blocks: the one estimator the plan, the design, the dry run and the bench use.

A block at orbit speed Omega averaging n revolutions takes (n + 1) orbit periods 2 pi / |Omega|:
the extra one finds the trigger before the first whole revolution. A list of orbit ratios
r = |Omega| / omega at spin omega is run in one or both whirl directions (two blocks per
ratio for both directions); per block a fixed overhead (settle hold and store) is added, and per point
the orbit drive's ramps: forward from the highest |Omega| down, backward back up, 2 x the
highest |Omega| at the ramp rate for both directions (once for one). Seconds, physical.
"""

from __future__ import annotations

from typing import overload

import numpy as np
from numpy.typing import ArrayLike

from reduction.whirl import Directions

TRIGGER_REVOLUTIONS = 1  # revolutions spent finding the trigger before a block's first whole one


def revolution_time(ratios: ArrayLike, spin: float, directions: Directions = Directions.BOTH) -> np.ndarray:
    """(k,) seconds of one revolution at each ratio, 2 pi / (r omega), summed over its whirl
    directions (two blocks per ratio for both)."""
    r = np.asarray(ratios, dtype=float)
    t: np.ndarray = Directions(directions).blocks * 2 * np.pi / (r * spin)
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


def list_time(
    ratios: ArrayLike, spin: float, revolutions: ArrayLike, directions: Directions = Directions.BOTH
) -> float:
    """Seconds averaging the blocks of ``ratios`` (each ratio's ``revolutions``, one count or one
    per ratio, in every direction), trigger revolutions included."""
    r = np.asarray(ratios, dtype=float)
    n = np.broadcast_to(np.asarray(revolutions, dtype=float), r.shape)
    return float(Directions(directions).blocks * np.sum(block_time(r * spin, n)))


def point_time(
    ratios: ArrayLike,
    spin: float,
    revolutions: ArrayLike,
    directions: Directions = Directions.BOTH,
    per_block_s: float = 0.0,
    ramp_rate: float | None = None,
) -> float:
    """Seconds of a point's blocks: :func:`list_time` + blocks x ``per_block_s`` (settle hold,
    store) + the orbit ramps at ``ramp_rate`` (rad/s per s; None: left out)."""
    r = np.asarray(ratios, dtype=float)
    blocks = Directions(directions).blocks * r.size
    ramps = 0.0 if ramp_rate is None else Directions(directions).blocks * float(np.max(r)) * spin / ramp_rate
    return list_time(r, spin, revolutions, directions) + blocks * per_block_s + ramps
