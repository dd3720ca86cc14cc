"""The least rig time that completes a point's information to a precision target.

A point has measured blocks already: their Fisher information I0 (p, p). Candidate blocks b
(a ratio in one or both whirl directions) add t_b / tau_b F_b for t_b seconds of acquisition
(tau_b the seconds of one revolution, F_b the information of one revolution). The completion
is the t >= 0 minimising the acquisition time sum_b t_b subject to every coefficient's
variance [(I0 + sum_b t_b / tau_b F_b)^-1]_jj at most goal_j^2: a convex program (the
variances are convex in t), solved by SLSQP with analytic gradients from a feasible start.
Each block kept also costs a fixed overhead (settle, store): the smallest is dropped and the
rest solved again while that lowers acquisition + overhead. With I0 = 0 this is
reduction.allocation's problem; with the information measured so far it is what the rest of
a sequential point should still measure (reduction.sequential). Pure numerics, SI.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from reduction.arrays import FloatArray
from reduction.errors import ReductionError

ACTIVE = 1e-6  # a block whose share of the completion's time is below this is not measured
_SCALE_STEPS = 60  # doublings tried for a feasible start

#: the variances over their goals at acquisition seconds t: (g (p,), its gradient (p, k))
Variances = Callable[[FloatArray], tuple[FloatArray, FloatArray]]


def _variances(I0: FloatArray, per_s: FloatArray, goal2: FloatArray) -> Variances:
    """g(t) (p,) = diag((I0 + sum t_b per_s_b)^-1) / goal^2 and its gradient (p, k)."""

    def at(t: FloatArray) -> tuple[FloatArray, FloatArray]:
        G = np.linalg.inv(I0 + np.einsum("k,kij->ij", t, per_s))
        grad = -np.einsum("ij,kjl,li->ik", G, per_s, G) / goal2[:, None]
        return np.diag(G) / goal2, grad

    return at


def _feasible(at: Variances, t: FloatArray) -> FloatArray:
    """``t`` scaled up (a factor >= 1, bisected to 1 %) until every variance meets its goal."""
    if np.max(at(t)[0]) <= 1.0:
        return t
    lo, hi = 1.0, 2.0
    for _ in range(_SCALE_STEPS):
        if np.max(at(hi * t)[0]) <= 1.0:
            break
        lo, hi = hi, 2 * hi
    else:
        raise ReductionError("completion: these candidate blocks cannot reach the goal")
    while hi / lo > 1.01:
        mid = np.sqrt(lo * hi)
        lo, hi = (lo, mid) if np.max(at(mid * t)[0]) <= 1.0 else (mid, hi)
    scaled: FloatArray = hi * t
    return scaled


def _solve(at: Variances, k: int, keep: np.ndarray, x0: FloatArray) -> FloatArray:
    """The least sum of t over the blocks ``keep`` (the others 0) meeting every goal, from ``x0``."""
    from scipy.optimize import minimize  # here: its import costs every command that plans a run 0.3 s

    def full(v: FloatArray) -> FloatArray:
        t = np.zeros(k)
        t[keep] = np.maximum(v, 0.0)
        return t

    res = minimize(
        lambda v: float(np.sum(v)),
        x0,
        jac=lambda v: np.ones_like(v),
        method="SLSQP",
        constraints=[
            {"type": "ineq", "fun": lambda v: 1.0 - at(full(v))[0], "jac": lambda v: -at(full(v))[1][:, keep]}
        ],
        bounds=[(0.0, None)] * keep.size,
        options={"maxiter": 200, "ftol": 1e-9},
    )
    return _feasible(at, full(res.x if np.all(np.isfinite(res.x)) else x0))


def completion(I0: FloatArray, F: FloatArray, tau: FloatArray, goal: FloatArray, overhead: FloatArray) -> FloatArray:
    """(k,) acquisition seconds per candidate block (0: not measured) that bring every
    standard error to at most ``goal`` (p,) SI in the least acquisition + overhead time.
    ``I0`` (p, p) the information measured so far (may be singular if the candidates complete
    it), ``F`` (k, p, p) one revolution's information per candidate, ``tau`` (k,) its seconds,
    ``overhead`` (k,) seconds each candidate costs when measured. ReductionError when the
    candidates cannot reach the goal."""
    k = tau.size
    at = _variances(np.asarray(I0, float), F / tau[:, None, None], np.asarray(goal, float) ** 2)
    try:
        t = _feasible(at, np.ones(k))
        t = _solve(at, k, np.arange(k), t)
    except np.linalg.LinAlgError as exc:
        raise ReductionError("completion: these candidate blocks cannot reach the goal") from exc

    def kept(t: FloatArray) -> FloatArray:
        """``t`` with the blocks below ACTIVE of the total set to 0 (not measured)."""
        return np.where(t > ACTIVE * np.sum(t), t, 0.0)

    def cost(t: FloatArray) -> float:
        return float(np.sum(t) + np.sum(overhead[kept(t) > 0]))

    while True:
        t = kept(t)
        active = np.flatnonzero(t)
        if active.size <= 1:
            return t
        smallest = active[np.argmin(t[active])]
        rest = active[active != smallest]
        try:
            trial = _solve(at, k, rest, t[rest] * (1 + t[smallest] / np.sum(t[rest])))
        except (ReductionError, np.linalg.LinAlgError):
            return t
        if cost(trial) >= cost(t):
            return t
        t = trial
