"""Sequential design of one operating point: after each block, the next orbit ratio and its revolutions.

The point's Fisher information is the sum over the blocks measured so far of n_b times the
per-revolution information at their ratio (reduction.allocation.revolution_information),
evaluated at the point's own current coefficients and measured per-revolution noise. From it
the least-time completion (reduction.completion) plans the rest of the point: the candidate
blocks (ratio, whirl direction) and their revolutions that bring every coefficient's
predicted relative standard error (standard error / scale) to the target in the least rig
time, each block kept paying the settle hold and store. The next block is the planned block
whose orbit is nearest the orbit drive's speed now (the shortest ramp), with its planned
revolutions (MIN_REVOLUTIONS .. MAX_REVOLUTIONS); after it the plan is made again from what
was measured. This lowers the largest predicted relative error per second of rig time over
the whole rest of the point, not block by block: a greedy choice of the single block that
lowers the largest error most per second chases one coefficient after another in small
blocks, each paying the settle hold (on the nominal kcd11 bearing, matching the paper list's
errors from a five-ratio initial list with ramps counted: 0.80 of the paper protocol's rig
time greedily, 0.65 planned; tests/design/test_sequential_design.py). The point stops when
every coefficient's predicted relative standard error is at most the target, or when no
planned block fits in the time cap (a block is shortened to fit, down to MIN_REVOLUTIONS).

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
from reduction.information import identified_errors, predicted_errors
from reduction.models import ModelSpec
from reduction.completion import completion
from reduction.rig_time import block_time, revolution_time
from reduction.whirl import Directions

MIN_REVOLUTIONS = 10  # the fewest revolutions a chosen block averages
MAX_REVOLUTIONS = 1000  # the most


class Choice(StrEnum):
    """Why the sequential design did what it did (stored per block)."""

    NEXT = "next block of the least-time plan to the target"
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
    """(p,) predicted standard error / scale of the blocks so far, ``info`` (p, p) their
    information (reduction.information); ReductionError when they cannot identify the model."""
    se = predicted_errors(info)
    if not np.all(np.isfinite(se)):
        raise ReductionError(
            "sequential design: the blocks so far cannot identify the model; run an initial list first"
        )
    relative: FloatArray = se / np.asarray(scales, dtype=float)
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
    list" asks every coefficient to reach. IdentifiabilityError naming the coefficients the
    list cannot identify (reduction.information.identified_errors)."""
    F = revolution_information(spec, theta, spin, radius, ratios, u_revolution, directions)
    r = ", ".join(f"{v:g}" for v in np.atleast_1d(np.asarray(ratios, dtype=float)))
    what = f"the reference list (ratios {r}, {Directions(directions).value}, {revolutions} revolutions)"
    return identified_errors(revolutions * F.sum(axis=0), spec, what)


def next_block(
    spec: ModelSpec,
    theta: ArrayLike,
    spin: float,
    radius: float,
    info: FloatArray,
    candidates: ArrayLike,
    noise_at: NoiseAt,
    scales: ArrayLike,
    *,
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
    options = tuple(Directions(d) for d in ((directions,) if isinstance(directions, str) else directions))
    blocks = [(float(ratio), d) for d in options for ratio in r]
    F = np.concatenate([revolution_information(spec, theta, spin, radius, r, noise_at(r), d) for d in options])
    tau = np.concatenate([revolution_time(r, spin, d) for d in options])
    overhead = np.concatenate([np.full(r.size, d.blocks * per_block_s) for d in options])
    goal = target * np.asarray(scales, dtype=float)
    t = _planned(np.asarray(info, dtype=float), F, tau, goal, overhead, r.size)
    ramps = [_ramp_s(ratio * spin, d, orbit_now, ramp_rate) for ratio, d in blocks]
    for b in sorted(np.flatnonzero(t > 0), key=lambda b: ramps[b]):  # the nearest orbit first
        ratio, d = blocks[b]
        n = int(np.clip(np.ceil(t[b] / tau[b] - 1e-9), MIN_REVOLUTIONS, MAX_REVOLUTIONS))
        while n >= MIN_REVOLUTIONS:
            seconds = d.blocks * (block_time(ratio * spin, n) + per_block_s) + ramps[b]
            if spent_s + seconds <= cap_s:
                after = relative_errors(info + n * F[b], scales)  # F[b]: block_information's per revolution
                return NextBlock(ratio, n, Choice.NEXT, float(seconds), before, after, d)
            n = min(n - 1, int(n * (cap_s - spent_s - ramps[b]) / seconds))
    return NextBlock(None, 0, Choice.CAP, 0.0, before, before)


def _planned(
    info: FloatArray, F: FloatArray, tau: FloatArray, goal: FloatArray, overhead: FloatArray, k: int
) -> FloatArray:
    """The completion (reduction.completion) over candidate blocks laid out direction by
    direction, ``k`` ratios ascending each: solved first on every second ratio, then on the
    ratios next to those it kept (a tenth of the solver's time on the 0.05 grid; the fine grid
    alone moves the optimum little)."""
    n = tau.size
    ratio = np.arange(n) % k
    coarse = np.flatnonzero((ratio % 2 == 0) | (ratio == k - 1))
    t = np.zeros(n)
    t[coarse] = completion(info, F[coarse], tau[coarse], goal, overhead[coarse])
    kept = np.flatnonzero(t > 0)
    near = {int(b + d) for b in kept for d in (-1, 0, 1) if 0 <= ratio[b] + d < k}
    fine = np.array(sorted(near))
    out = np.zeros(n)
    out[fine] = completion(info, F[fine], tau[fine], goal, overhead[fine])
    return out


def _ramp_s(orbit: float, direction: Directions, orbit_now: float | None, ramp_rate: float | None) -> float:
    """Seconds the orbit drive ramps from ``orbit_now`` to the block's first orbit speed."""
    if orbit_now is None or ramp_rate is None:
        return 0.0
    return abs(direction.whirls[0].sign * orbit - orbit_now) / ramp_rate
