"""The adequacy test of ``power:auto``, adjusted for the exponent chosen on the same data.

``power:auto`` fits ``power:M`` for each M in 1..4 and keeps the one with the least residual,
so the constant model is tested against the best of several frequency-dependent models: the
chosen test's own p-value is optimistic (5 to 9 % "supported" at alpha 5 % over five seeds
when Z is constant, tests/reduction/test_power_auto_adequacy.py). The adjusted p-value is the
probability, with the constant model true, that the p-value of the candidate power:auto keeps
(the least residual) is at most the one observed.

Null geometry (equations whitened by their standard deviations, Gaussian noise e ~ N(0, I)):
candidate M's statistic is s_M = |Q_M^T e|^2, Q_M an orthonormal basis of its columns made
orthogonal to the constant model's (q_M = p_M - p_0 of them); with known noise p_M is
chi2_sf(s_M, q_M), with unknown noise the F-test's on RSS_0 = |e|^2 - |P_0 e|^2 and
RSS_M = RSS_0 - s_M. Only e's components in the span U of every Q_M matter besides the
chi2(4n - p_0 - d) of the rest, so :class:`Selection` keeps C_M = U^T Q_M (d x q_M, d <= the
sum of q_M) and the p-value is drawn by Monte Carlo over z ~ N(0, I_d) with a fixed seed
(reproducible). Exact for ols and wls with the fit's weights and Gaussian noise; for tls and
iv, and with effective variances that depend on the fit, the weights are those of the chosen
fit (an approximation of the candidates' correlation; each p_M keeps its exact marginal).

Pure numerics; dimensionless.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from reduction import distributions as dist
from reduction.arrays import FloatArray
from reduction.regression import column_scale

DRAWS = 20_000  # Monte Carlo draws: standard error 0.15 % at p = 0.05
SEED = 20_260_529  # fixed: the same table gives the same adjusted p-value
MIN_HITS = 10  # fewer draws at or below the observed p: the Bonferroni bound k p instead
#: directions of the candidates' span weaker than this (relative) are rounding, not a direction: a
#: candidate's basis leaks ~1e-13 into the constant's span, which the default rank tolerance keeps
SPAN_RTOL = 1e-8


@dataclass(frozen=True)
class Selection:
    """The null geometry of a choice among candidate frequency-dependent models (module doc):
    ``exponents`` (M of each candidate), ``extra`` (C_M, d x q_M each), ``dof`` (4n - p_M each)
    and ``rest_dof`` (4n - p_0 - d, the residual directions no candidate reaches)."""

    exponents: tuple[int, ...]
    extra: tuple[FloatArray, ...]
    dof: tuple[int, ...]
    rest_dof: int

    def p_value(self, p_chosen: float, known_noise: bool, draws: int = DRAWS) -> float:
        """P(p_M* <= ``p_chosen``) with the constant model true, M* the candidate of the least
        residual in each draw (the largest s_M: power:auto's choice), within [p_chosen, min(1,
        k p_chosen)]; the Bonferroni bound where fewer than MIN_HITS draws reach ``p_chosen``
        (the draws cannot resolve so small a probability)."""
        k = len(self.extra)
        bound = min(1.0, k * p_chosen)
        if k < 2:
            return p_chosen
        z, rss0 = _draws(self.extra[0].shape[0], self.rest_dof, draws)
        s = np.stack([np.sum((C.T @ z) ** 2, axis=0) for C in self.extra])  # k x draws
        chosen = np.argmax(s, axis=0)  # the least residual: RSS_M (chi2_M) = RSS_0 (chi2_0) - s_M
        s = s[chosen, np.arange(draws)]
        qs = [C.shape[1] for C in self.extra]
        if known_noise:
            reached = s >= np.array([dist.chi2_isf(p_chosen, q) for q in qs])[chosen]
        else:  # F = (s / q) / ((rss0 - s) / dof) at least its quantile
            f = np.array([dist.f_isf(p_chosen, q, dof) for q, dof in zip(qs, self.dof)])
            reached = s * np.array(self.dof)[chosen] >= f[chosen] * np.array(qs)[chosen] * (rss0 - s)
        hits = int(np.count_nonzero(reached))
        if hits < MIN_HITS:
            return bound
        return float(min(max(hits / draws, p_chosen), bound))


@lru_cache(maxsize=4)
def _draws(d: int, rest_dof: int, draws: int) -> tuple[FloatArray, FloatArray]:
    """z ~ N(0, I_d) (d x draws) and RSS_0 = |z|^2 + chi2(rest_dof) of each draw, from SEED
    (the same for every table of the same shape: kept for the next; read-only)."""
    rng = np.random.default_rng(SEED)
    z = rng.standard_normal((d, draws))
    rss0 = np.sum(z**2, axis=0) + (rng.chisquare(rest_dof, draws) if rest_dof > 0 else 0.0)
    z.flags.writeable = rss0.flags.writeable = False
    return z, rss0


def _orthonormal(M: FloatArray, rank: int) -> FloatArray:
    """The first ``rank`` left singular vectors of M (columns as given: scale them first)."""
    U, _, _ = np.linalg.svd(M, full_matrices=False)
    return U[:, :rank]


def selection(
    constant: FloatArray, candidates: dict[int, FloatArray], weights: FloatArray, equations: int | None = None
) -> Selection:
    """The :class:`Selection` of regression matrices: ``constant`` (4n x p_0) and, per exponent,
    the candidate's (4n x p_M, nested: its columns span the constant's), rows weighted by
    ``weights`` (1 / standard deviation of each equation). ``equations``: 4n where the rows given
    are a triangular factor of the weighted matrices side by side (the same geometry, fewer rows)."""
    w = weights[:, None]
    p0 = constant.shape[1]
    n = constant.shape[0] if equations is None else equations
    Q0 = _orthonormal(column_scale(constant * w)[0], p0)
    bases, dof = [], []
    for A in candidates.values():
        Aw = column_scale(A * w)[0]  # scaled before the constant's span is taken out: what is left
        Aw -= Q0 @ (Q0.T @ Aw)  # of the constant's own columns is rounding, not a direction
        bases.append(_orthonormal(Aw, A.shape[1] - p0))
        dof.append(n - A.shape[1])
    U, s, _ = np.linalg.svd(np.hstack(bases), full_matrices=False)
    d = min(int(np.count_nonzero(s > SPAN_RTOL * s[0])), n - p0)  # the candidates' span beside the constant's
    U = U[:, :d]
    return Selection(tuple(candidates), tuple(U.T @ Q for Q in bases), tuple(dof), n - p0 - d)
