"""Sequential design of one operating point: after each block, the next orbit ratio and its revolutions.

The point's Fisher information is the sum over the blocks measured so far of n_b times the
per-revolution information at their ratio (reduction.allocation.revolution_information),
evaluated at the point's own current coefficients and measured per-revolution noise. The
next block is the (ratio, revolutions) of the candidates that lowers the largest predicted
relative standard error (standard error / scale) most per second of rig time, measured as
the gain in its precision 1 / error^2 (which grows with the revolutions as the information
does: a gain in the error itself shrinks with every revolution and would favour small blocks,
each paying the settle hold; on the nominal kcd11 bearing, matching the paper list's errors
from a five-ratio initial list, the point then takes 0.81 instead of 0.94 of the paper
protocol's rig time, ramps counted) (the block in
its whirl direction(s), trigger revolution included (reduction.rig_time), plus the per-block
overhead and, given the orbit speed now and the ramp rate, the orbit drive's ramp to it). The
point stops when every coefficient's predicted relative standard error is at most the target,
or when the next block would pass the time cap.

Candidates come from the caller (the drives' band, away from Omega/omega = 1:
reduction.frequency_list.allowed_ratios). The information must already be invertible (run
an initial list first, e.g. the model test's K spread ratios). Pure numerics, SI.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum

import numpy as np
from numpy.typing import ArrayLike

from reduction.allocation import revolution_information
from reduction.arrays import FloatArray, NoiseAt
from reduction.errors import ReductionError
from reduction.models import ModelSpec
from reduction.rig_time import block_time
from reduction.whirl import Directions

STEP_REVOLUTIONS = (10, 20, 50, 100, 200)  # block sizes tried at each candidate ratio


class Choice(StrEnum):
    """Why the sequential design did what it did (stored per block)."""

    NEXT = "largest error reduced most per second"
    TARGET = "every coefficient at its target"
    CAP = "time cap reached"


@dataclass(frozen=True)
class NextBlock:
    """The decision: ``ratio`` and ``revolutions`` of the next block (None, 0 when stopping),
    why, the block's rig seconds, and the predicted relative standard errors (p,) before and
    after it (after = before when stopping); ``direction`` its whirl directions."""

    ratio: float | None
    revolutions: int
    reason: Choice
    seconds: float
    before: FloatArray
    after: FloatArray
    direction: Directions = Directions.BOTH


def block_information(
    spec: ModelSpec,
    theta: ArrayLike,
    spin: float,
    radius: float,
    ratio: float,
    u_revolution: ArrayLike,
    revolutions: int,
    directions: Directions = Directions.BOTH,
) -> FloatArray:
    """(p, p) information of one measured block (all its directions): revolutions x the
    per-revolution information at ``ratio`` with the measured noise u (4,)."""
    F = revolution_information(spec, theta, spin, radius, [ratio], np.asarray(u_revolution, float)[None], directions)
    info: FloatArray = revolutions * F[0]
    return info


def relative_errors(info: ArrayLike, scales: ArrayLike) -> FloatArray:
    """(p,) predicted standard error / scale; ReductionError when ``info`` is singular."""
    try:
        cov = np.linalg.inv(np.asarray(info, dtype=float))
    except np.linalg.LinAlgError as exc:
        raise ReductionError(
            "sequential design: the blocks so far cannot identify the model; run an initial list first"
        ) from exc
    d = np.diag(cov)
    if not np.all(np.isfinite(d)) or np.any(d <= 0):
        raise ReductionError(
            "sequential design: the blocks so far cannot identify the model; run an initial list first"
        )
    relative: FloatArray = np.sqrt(d) / np.asarray(scales, dtype=float)
    return relative


def reference_errors(
    spec: ModelSpec,
    theta: ArrayLike,
    spin: float,
    radius: float,
    ratios: ArrayLike,
    u_revolution: ArrayLike,
    revolutions: int,
    directions: Directions = Directions.BOTH,
) -> FloatArray:
    """(p,) predicted standard errors (SI) of a reference list: ``ratios`` each averaging
    ``revolutions`` in ``directions``, per-revolution noise u (k, 4) - what "match the paper's
    list" asks every coefficient to reach."""
    F = revolution_information(spec, theta, spin, radius, ratios, u_revolution, directions)
    return relative_errors(revolutions * F.sum(axis=0), np.ones(F.shape[1]))


def next_block(
    spec: ModelSpec,
    theta: ArrayLike,
    spin: float,
    radius: float,
    info: FloatArray,
    candidates: ArrayLike,
    noise_at: NoiseAt,
    scales: ArrayLike,
    target: float,
    spent_s: float,
    cap_s: float,
    per_block_s: float = 0.0,
    directions: Directions | Sequence[Directions] = Directions.BOTH,
    orbit_now: float | None = None,
    ramp_rate: float | None = None,
) -> NextBlock:
    """The next block of the point (module doc). ``info`` (p, p) so far, ``noise_at(ratios) ->
    (k, 4)`` per-revolution noise, ``scales`` (p,) SI, ``target`` a fraction, ``spent_s`` the
    rig seconds spent on the point, ``cap_s`` its cap, ``per_block_s`` settle + store per block,
    ``directions`` one whirl option or several to choose from;
    ``orbit_now`` (rad/s, signed) and ``ramp_rate`` (rad/s per s) add the ramp to each block."""
    before = relative_errors(info, scales)
    if float(np.max(before)) <= target:
        return NextBlock(None, 0, Choice.TARGET, 0.0, before, before)
    r = np.asarray(candidates, dtype=float)
    n = np.asarray(STEP_REVOLUTIONS, dtype=float)
    s = np.asarray(scales, dtype=float)
    options = tuple(Directions(d) for d in ((directions,) if isinstance(directions, str) else directions))
    best: tuple[float, float, int, float, FloatArray, Directions] | None = None
    for d in options:  # every (ratio, revolutions) of a direction at once: (k, m) candidates
        F = revolution_information(spec, theta, spin, radius, r, noise_at(r), d)
        ramp = np.array([_ramp_s(ratio * spin, d, orbit_now, ramp_rate) for ratio in r])
        seconds = d.blocks * (block_time(r[:, None] * spin, n[None]) + per_block_s) + ramp[:, None]
        after = _batch_relative(info[None, None] + n[None, :, None, None] * F[:, None], s)  # (k, m, p)
        rate = (1.0 / np.max(after, axis=2) ** 2 - 1.0 / float(np.max(before)) ** 2) / seconds
        rate = np.where(spent_s + seconds <= cap_s, rate, -np.inf)
        k, j = np.unravel_index(int(np.argmax(rate)), rate.shape)
        if np.isfinite(rate[k, j]) and (best is None or rate[k, j] > best[0]):
            best = (float(rate[k, j]), float(r[k]), int(n[j]), float(seconds[k, j]), after[k, j], d)
    if best is None or best[0] <= 0:
        return NextBlock(None, 0, Choice.CAP, 0.0, before, before)
    _, ratio, revs, secs, aft, d = best
    return NextBlock(ratio, revs, Choice.NEXT, secs, before, aft, d)


def _batch_relative(info: FloatArray, scales: FloatArray) -> FloatArray:
    """(..., p) standard error / scale of a stack of informations (..., p, p); inf where singular."""
    try:
        d = np.diagonal(np.linalg.inv(info), axis1=-2, axis2=-1)
    except np.linalg.LinAlgError:
        return np.full(info.shape[:-1], np.inf)
    relative: FloatArray = np.where(d > 0, np.sqrt(np.abs(d)), np.inf) / scales
    return relative


def _ramp_s(orbit: float, direction: Directions, orbit_now: float | None, ramp_rate: float | None) -> float:
    """Seconds the orbit drive ramps from ``orbit_now`` to the block's first orbit speed."""
    if orbit_now is None or ramp_rate is None:
        return 0.0
    return abs(direction.whirls[0].sign * orbit - orbit_now) / ramp_rate
