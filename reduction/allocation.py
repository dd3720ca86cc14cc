"""Revolutions per orbit frequency: the least rig time that reaches a precision target.

A block at orbit ratio r = |Omega|/omega costs its revolutions times the orbit period
2 pi / (r omega) plus a fixed overhead (settle, store). Averaging n revolutions divides the
per-revolution noise variance by n, so a block's Fisher information is n times its
per-revolution information F_b (:func:`revolution_information`). The covariance of the
coefficients is (sum_b n_b F_b)^-1.

:func:`allocate` finds, for a set of candidate ratios, the revolutions per ratio (both
whirl directions of a ratio average the same count) that bring every coefficient's
standard error to at most ``target`` x its scale in the least rig time:

1. time shares: with w_b the fraction of the acquisition time spent at ratio b, the
   information per second of acquisition is I(w) = sum_b (w_b / tau_b) F_b (tau_b the time
   of one revolution at b, both directions). The acquisition time that reaches the target is
   T = max_j [I(w)^-1]_jj / (target s_j)^2, convex in w; minimised over the simplex (SLSQP on
   the epigraph, analytic gradients).
2. support: each ratio kept costs the per-block overhead; the ratio with the smallest share
   is dropped (and the shares solved again) while that lowers acquisition + overhead and the
   rest still identifies the model.
3. counts: n_b = ceil(w_b T / tau_b), at least ``min_revolutions``, then scaled up together
   until the rounded counts reach the target.

Everything SI; ratios are fractions of the spin speed; no I/O.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from reduction.arrays import FloatArray, IntArray
from reduction.design import design_orbits
from reduction.errors import ReductionError
from reduction.impedance import forces, impedance, real_rows, regressors
from reduction.information import predicted_errors
from reduction.models import ModelSpec
from reduction.noise import equation_variances
from reduction.rig_time import Ways, blocks_per_ratio, revolution_time
from reduction.whirl import Directions
from rigunits import HZ

MIN_SHARE = 1e-9  # smallest time share the solver may give a ratio (keeps I(w) invertible)
NEAR = 2  # a constrained exchange moves a ratio at most this many grid steps

#: the objective's pieces at time shares w: (g (p,), its gradient (p, k))
WorstVariance = Callable[[FloatArray], tuple[FloatArray, FloatArray]]
#: may the candidates of these indices form a list (None: any may)
Admissible = Callable[[list[int]], bool]


@dataclass(frozen=True)
class Allocation:
    """Revolutions per ratio (ratios ascending, all directions of a ratio alike), their
    predicted standard errors (p,) SI, the worst of se / scale, and the rig time split into
    acquisition (s, sum of revolutions x period) and overhead (s, blocks x overhead)."""

    ratios: tuple[float, ...]
    revolutions: tuple[int, ...]
    std_errors: FloatArray
    worst: float
    acquisition_s: float
    overhead_s: float
    whirl: tuple[Directions, ...] = ()  # per ratio its directions (a ratio may be there once per direction)

    @property
    def rig_time_s(self) -> float:
        return self.acquisition_s + self.overhead_s


def revolution_information(
    spec: ModelSpec,
    theta: ArrayLike,
    spin: float,
    radius: float,
    ratios: ArrayLike,
    u_revolution: ArrayLike,
    directions: Ways = Directions.BOTH,
) -> FloatArray:
    """(k, p, p) Fisher information of ONE revolution at each ratio (all its directions: one
    for every ratio, or one per ratio), circular orbits of ``radius`` (m), per-revolution noise
    u (k, 4) of x, y (m), fx, fy (N); displacement noise is propagated through Z at ``theta``."""
    r = np.atleast_1d(np.asarray(ratios, dtype=float))
    u = np.broadcast_to(np.asarray(u_revolution, dtype=float), (r.size, 4))
    if not isinstance(directions, str):  # one per ratio: each direction's ratios on their own
        ways = np.array([Directions(d).value for d in directions])
        out = np.zeros((r.size, spec.n_coefficients, spec.n_coefficients))
        for w in set(ways):
            at = ways == w
            out[at] = revolution_information(spec, theta, spin, radius, r[at], u[at], Directions(w))
        return out
    per = Directions(directions).blocks
    orbit, x, y = design_orbits(r * spin / HZ, directions, radius)
    A = real_rows(regressors(spec, orbit, x, y))  # (4 k per, p)
    var = equation_variances(np.repeat(u, per, axis=0), impedance(spec, np.asarray(theta, float), orbit))
    if np.any(var <= 0):
        raise ReductionError("revolution_information: every equation needs a noise > 0")
    Aw = (A / np.sqrt(var)[:, None]).reshape(r.size, 4 * per, -1)
    info: FloatArray = np.einsum("kei,kej->kij", Aw, Aw)
    return info


def _worst_variance(F: FloatArray, scales: FloatArray) -> WorstVariance:
    """Objective pieces at shares w: g(w) (p,) = diag(I^-1) / scales^2 and its (p, k) gradient
    (diag(I^-1) / s^2 = diag((S I S)^-1) with S = diag(scales))."""
    Fs = F * np.outer(scales, scales)[None]

    def at(w: FloatArray) -> tuple[FloatArray, FloatArray]:
        info = np.einsum("k,kij->ij", w, Fs)
        G = np.linalg.inv(info)
        g = np.diag(G)
        GF = np.einsum("ij,kjl->kil", G, Fs)  # (k, p, p)
        grad = -np.einsum("kil,li->ik", GF, G)  # d g_i / d w_k = -(G F_k G)_ii
        return g, grad

    return at


def time_shares(F: ArrayLike, tau: ArrayLike, scales: ArrayLike) -> tuple[FloatArray, float]:
    """(w (k,), T): acquisition-time shares minimising the acquisition time T (s) at which
    every coefficient's standard error equals its ``scales`` entry. F (k, p, p) information
    per revolution, tau (k,) seconds per revolution."""
    info, times, s = np.asarray(F, float), np.asarray(tau, float), np.asarray(scales, float)
    k = times.size
    per_second = info / times[:, None, None]
    at = _worst_variance(per_second, s)
    w0 = np.full(k, 1.0 / k)
    if not np.all(np.isfinite(predicted_errors(np.einsum("k,kij->ij", w0, per_second)))):
        raise ReductionError("time_shares: these ratios cannot identify the model")
    g0, _ = at(w0)
    z0 = float(np.max(g0))

    def safe(w: FloatArray) -> tuple[FloatArray, FloatArray]:
        try:
            return at(np.maximum(w, MIN_SHARE))
        except np.linalg.LinAlgError:
            return np.full(s.size, 1e30), np.zeros((s.size, k))

    cons = [
        {
            "type": "ineq",
            "fun": lambda v: v[-1] - safe(v[:-1])[0] / z0,
            "jac": lambda v: np.hstack([-safe(v[:-1])[1] / z0, np.ones((s.size, 1))]),
        },
        {"type": "eq", "fun": lambda v: np.sum(v[:-1]) - 1.0, "jac": lambda v: np.append(np.ones(k), 0.0)[None]},
    ]
    from scipy.optimize import minimize  # here: its import costs every command that plans a run 0.3 s

    res = minimize(
        lambda v: v[-1],
        np.append(w0, 1.0),
        jac=lambda v: np.append(np.zeros(k), 1.0),
        method="SLSQP",
        constraints=cons,
        bounds=[(MIN_SHARE, 1.0)] * k + [(0, None)],
        options={"maxiter": 300, "ftol": 1e-10},
    )
    w: FloatArray = np.maximum(res.x[:-1], MIN_SHARE)
    w = w / w.sum()
    g, _ = at(w)
    if float(np.max(g)) > z0:  # the solver did worse than the even split
        w, g = w0, g0
    return w, float(np.max(g))


def _cost(
    F: FloatArray,
    tau: FloatArray,
    s: FloatArray,
    per_block: float | FloatArray,
    keep: list[int],
    admissible: Admissible | None = None,
) -> tuple[float, FloatArray, float]:
    """(total s, shares, acquisition s) of the ratios ``keep``; total inf (and no shares) when
    they cannot identify the model or ``admissible(keep)`` says no."""
    if admissible is not None and not admissible(keep):
        return float("inf"), np.empty(0), float("inf")
    try:
        w, T = time_shares(F[keep], tau[keep], s)
    except ReductionError:
        return float("inf"), np.empty(0), float("inf")
    return T + float(np.sum(np.broadcast_to(per_block, tau.shape)[keep])), w, T


def _support(
    F: FloatArray, tau: FloatArray, s: FloatArray, per_block: float | FloatArray, admissible: Admissible | None = None
) -> tuple[IntArray, FloatArray, float]:
    """The ratios worth their overhead: from all, drop the one with the smallest share while
    that lowers acquisition + overhead; then exchange one kept ratio for another (or drop
    one) while that helps. With ``admissible(indices)`` every list tried must pass it: the
    drop takes the smallest share whose removal passes, and an exchange moves a ratio at
    most ``NEAR`` grid steps (a local search: the constrained lists are long). Returns (kept
    indices, their shares, acquisition s)."""
    keep = list(range(tau.size))
    ok = admissible or (lambda k: True)
    if not ok(keep):
        raise ReductionError("allocate: the list constraint refuses even all these ratios together")
    best, w, T = _cost(F, tau, s, per_block, keep, admissible)
    if not np.isfinite(best):
        raise ReductionError("allocate: these ratios cannot identify the model")
    while len(keep) > 1:
        trials = [t for t in (keep[:i] + keep[i + 1 :] for i in np.argsort(w)) if ok(t)]
        if not trials:
            break
        c, w2, T2 = _cost(F, tau, s, per_block, trials[0], admissible)
        if c >= best:
            break
        keep, best, w, T = trials[0], c, w2, T2
    reach = tau.size if admissible is None else NEAR
    improved = True
    while improved:
        improved = False
        moves = [keep[:i] + keep[i + 1 :] for i in range(len(keep)) if len(keep) > 1] + [
            sorted(keep[:i] + [g] + keep[i + 1 :])
            for i in range(len(keep))
            for g in range(tau.size)
            if g not in keep and abs(g - keep[i]) <= reach
        ]
        for trial in moves:
            c, w2, T2 = _cost(F, tau, s, per_block, trial, admissible)
            if c < best * (1 - 1e-6):
                keep, best, w, T, improved = trial, c, w2, T2, True
    return np.array(keep, dtype=np.int64), w, T


def _counts(
    F: FloatArray, tau: FloatArray, scales: FloatArray, w: FloatArray, T: float, min_revolutions: int
) -> tuple[IntArray, float]:
    """Rounded revolutions (k,) reaching the target, and their worst variance ratio."""
    n = np.maximum(np.ceil(w * T / tau - 1e-9), min_revolutions)
    for _ in range(50):
        info = np.einsum("k,kij->ij", n, F * np.outer(scales, scales)[None])
        worst = float(np.max(np.diag(np.linalg.inv(info))))
        if worst <= 1.0 + 1e-9:
            return n.astype(int), worst
        n = np.maximum(np.ceil(n * worst), min_revolutions)
    return n.astype(int), worst


def choose_blocks(
    F: FloatArray,
    tau: FloatArray,
    scales: FloatArray,
    per_block: float | FloatArray,
    admissible: Admissible | None = None,
    min_revolutions: int = 10,
) -> tuple[IntArray, IntArray, float]:
    """The candidate blocks worth their overhead and their revolutions: (kept indices, counts,
    acquisition s). F (k, p, p) information of one revolution of each candidate, tau (k,) its
    seconds, ``scales`` (p,) the standard errors to reach, ``per_block`` s of overhead per
    candidate kept (one for all or (k,)), ``admissible(kept indices)``: may these form a list. A candidate is any
    block: a ratio in both directions (as :func:`allocate` builds them) or one direction."""
    keep, w, T = _support(F, tau, scales, per_block, admissible)
    n, _ = _counts(F[keep], tau[keep], scales, w, T, min_revolutions)
    return keep, n, float(np.sum(n * tau[keep]))


def allocate(
    spec: ModelSpec,
    theta: ArrayLike,
    spin: float,
    radius: float,
    ratios: ArrayLike,
    u_revolution: ArrayLike,
    scales: ArrayLike,
    *,
    target: float = 1.0,
    block_overhead: float = 0.0,
    min_revolutions: int = 10,
    directions: Ways = Directions.BOTH,
    admissible: Callable[[FloatArray], bool] | None = None,
    also: Sequence[tuple[ModelSpec, ArrayLike, ArrayLike]] = (),
) -> Allocation:
    """Least-rig-time revolutions per ratio (a subset of ``ratios``) bringing every
    coefficient's standard error to at most ``target`` x ``scales`` (p,) SI; u_revolution
    (k, 4) per-revolution noise at each of ``ratios`` (or (4,) for all); ``block_overhead``
    s per block (settle + store); every kept block averages at least ``min_revolutions``;
    ``admissible(kept ratios (k,)) -> bool`` limits the lists considered (e.g.
    reduction.adequacy_design.spread_ok); ``directions``: one for every ratio, or one per
    entry of ``ratios`` (a ratio may then be there once per direction, each its own block);
    ``also``: further (spec, theta, scales) whose
    coefficients must reach ``target`` x their scales too (fitted to the same blocks; the
    information is block-diagonal over the models). The standard errors returned are
    ``spec``'s."""
    r = np.asarray(ratios, dtype=float)
    order = np.argsort(r, kind="stable")
    r = r[order]
    ways = [Directions(directions)] * r.size if isinstance(directions, str) else [Directions(d) for d in directions]
    ways = [ways[i] for i in order]
    u = (
        np.broadcast_to(np.asarray(u_revolution, dtype=float), (len(order), 4))[order]
        if np.ndim(u_revolution) == 2
        else np.asarray(u_revolution, dtype=float)
    )
    if not target > 0:
        raise ReductionError(f"allocate: target must be > 0, got {target:g}")
    models = [(spec, theta, scales), *also]
    s = np.concatenate([np.asarray(sc, dtype=float) for _, _, sc in models]) * target
    F = block_diagonal([revolution_information(m, th, spin, radius, r, u, ways) for m, th, _ in models])
    tau = revolution_time(r, spin, ways)
    per_block = block_overhead * blocks_per_ratio(r.size, ways)
    ok: Admissible | None = None if admissible is None else (lambda keep: admissible(r[keep]))
    keep, n, _ = choose_blocks(F, tau, s, per_block, ok, min_revolutions)
    p = spec.n_coefficients
    se = predicted_errors(np.einsum("k,kij->ij", n, F[keep][:, :p, :p]))
    return Allocation(
        tuple(float(v) for v in r[keep]),
        tuple(int(v) for v in n),
        se,
        float(np.max(se / np.asarray(scales, float))),
        float(np.sum(n * tau[keep])),
        float(np.sum(per_block[keep])),
        tuple(ways[i] for i in keep),
    )


def block_diagonal(parts: Sequence[FloatArray]) -> FloatArray:
    """(k, P, P) per-ratio information of several models side by side (P the sum of their p)."""
    k, sizes = parts[0].shape[0], [f.shape[1] for f in parts]
    out = np.zeros((k, sum(sizes), sum(sizes)))
    at = 0
    for f, p in zip(parts, sizes):
        out[:, at : at + p, at : at + p] = f
        at += p
    return out


def adaptive_targets(
    spec: ModelSpec,
    theta: ArrayLike,
    spin: float,
    radius: float,
    ratios: ArrayLike,
    revolutions: ArrayLike,
    u_revolution: ArrayLike,
    directions: Ways = Directions.BOTH,
) -> FloatArray:
    """(k,) relative standard uncertainty (fraction) of the noisiest phasor after ``revolutions``
    (k,) at each ratio: max over x, y (u / radius) and fx, fy (u / |f|, f = -Z d on the
    circular orbit at ``theta``, the smaller force of the ratio's directions). As an adaptive
    averaging target it makes a block stop near its allocated count at the stated noise."""
    r = np.atleast_1d(np.asarray(ratios, dtype=float))
    u = np.broadcast_to(np.asarray(u_revolution, dtype=float), (r.size, 4))
    per = blocks_per_ratio(r.size, directions).astype(int)
    orbit, x, y = design_orbits(r * spin / HZ, directions, radius)
    fx, fy = forces(impedance(spec, np.asarray(theta, float), orbit), x, y)
    f = np.minimum.reduceat(np.minimum(np.abs(fx), np.abs(fy)), np.cumsum(per) - per)
    rel = np.maximum(np.max(u[:, :2], axis=1) / radius, np.max(u[:, 2:], axis=1) / f)
    out: FloatArray = rel / np.sqrt(np.asarray(revolutions, dtype=float))
    return out
