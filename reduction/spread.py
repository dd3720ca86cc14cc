"""Two protocols' spreads compared over repeated runs: the ratio of the coefficients' sample
standard deviations, its confidence interval, and whether a goal on the worst ratio is shown.

Over n_a and n_b independent runs with normally scattered estimates, (s_a / sigma_a)^2 /
(s_b / sigma_b)^2 is F(n_a - 1, n_b - 1)-distributed, so the interval of sigma_a / sigma_b at
confidence ``level`` is [r / sqrt(F(n_a - 1, n_b - 1)), r sqrt(F(n_b - 1, n_a - 1))], r = s_a /
s_b, F the quantile with upper tail (1 - level) / 2 (:func:`spread_ratio_interval`).

One ratio scatters by about 1/sqrt(n - 1) (0.23 at 20 runs each), and the largest of p ratios
read off the same runs is biased upward as an estimate of the largest true ratio: with eleven
coefficients at 20 runs it reads about 1.2 when no true ratio exceeds 1.03
(bench/bench_spread.py). A goal on the worst ratio is therefore decided coefficient by
coefficient (:func:`spread_verdict`), each interval at the Bonferroni level 1 - (1 - level) / p
so that the p intervals hold together with probability at least ``level``: met when every
interval lies at or below the goal, missed when one lies above it, else undecided at that many
runs. Pure numerics.
"""

from __future__ import annotations

from enum import StrEnum

import numpy as np
from numpy.typing import ArrayLike

from reduction import distributions as dist
from reduction.arrays import FloatArray
from reduction.errors import ReductionError

LEVEL = 0.90  # two-sided: each bound is a one-sided 95 % bound


class SpreadVerdict(StrEnum):
    """What repeated runs show about a goal on the worst spread ratio."""

    MET = "met"  # every coefficient's upper bound at most the goal
    MISSED = "missed"  # some coefficient's lower bound above the goal
    UNDECIDED = "undecided"  # neither, at this many runs


def spread_ratio_interval(ratio: ArrayLike, runs_a: int, runs_b: int, level: float = LEVEL) -> FloatArray:
    """(..., 2) confidence interval of sigma_a / sigma_b for each read ratio s_a / s_b of the
    sample standard deviations (ddof 1) of ``runs_a`` and ``runs_b`` independent runs."""
    if min(runs_a, runs_b) < 2 or not 0 < level < 1:
        raise ReductionError("a spread ratio's interval needs two runs on each side and 0 < level < 1")
    tail = (1 - level) / 2
    r = np.asarray(ratio, dtype=float)
    lo = r / np.sqrt(dist.f_isf(tail, runs_a - 1, runs_b - 1))
    hi = r * np.sqrt(dist.f_isf(tail, runs_b - 1, runs_a - 1))
    out: FloatArray = np.stack([lo, hi], axis=-1)
    return out


def spread_verdict(ratios: ArrayLike, runs_a: int, runs_b: int, goal: float, level: float = LEVEL) -> SpreadVerdict:
    """Whether the runs show every true spread ratio at most ``goal`` (met), one above it
    (missed), or neither (undecided); ``ratios`` (p,) read off ``runs_a`` and ``runs_b`` runs,
    the p intervals jointly at ``level`` (Bonferroni)."""
    r = np.atleast_1d(np.asarray(ratios, dtype=float))
    bounds = spread_ratio_interval(r, runs_a, runs_b, 1 - (1 - level) / r.size)
    if np.any(bounds[..., 0] > goal):
        return SpreadVerdict.MISSED
    if np.all(bounds[..., 1] <= goal):
        return SpreadVerdict.MET
    return SpreadVerdict.UNDECIDED
