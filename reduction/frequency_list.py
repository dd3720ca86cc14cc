"""Orbit-frequency lists designed on the Cramer-Rao bound: fewer, better placed frequencies.

A list is a set of orbit ratios r = |Omega|/omega at one spin speed omega, each run in the
given whirl directions with circular orbits of one radius. Its predicted standard errors are
the square roots of the diagonal of :func:`reduction.design.predicted_covariance` for the
stated noise: ``u_revolution`` (4,) is the standard uncertainty sqrt(E|err|^2) of ONE
revolution's phasors x, y (m), fx, fy (N); a block averaging n revolutions has u / sqrt(n).
Measured noise depends on the orbit frequency (runout and spindle-bearing tones leak into
the fundamental differently at each ratio): give it as (m, 4) at ``noise_ratios`` (m,). A
list identifies the model by the rank rule identification refuses a table by
(:func:`reduction.rank.determined_rank`); one that does not has no standard errors, and its
refusal names the coefficients it leaves undetermined.

Relative standard error of a coefficient: its standard error divided by the size of its
matrix, ``coefficient_scales``: the RMS of the diagonal entries of that matrix's constant
term at the prior coefficients, divided by omega^r for a term of order r (so Omega^r K_r is
compared with K at Omega = omega). A cross-coupling or a frequency-dependent term that is
zero in the prior keeps a finite relative error this way. Given ``scales`` instead (e.g. the
standard errors of a reference list), "relative" is relative to them: a target of 1 then asks
for every coefficient at least as precise as with the reference.

:func:`propose` searches a grid of allowed ratios (inside the drives' band, away from
r = 1 where the orbit cannot be told from the spindle's runout) with an exchange algorithm:
start from an evenly spread list, move one frequency at a time to the grid point that lowers
the worst relative standard error most, until no move helps. With a target it returns the
fewest frequencies whose best list reaches it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from reduction.arrays import FloatArray
from reduction.design import design_orbits, predicted_covariance
from reduction.errors import ReductionError
from reduction.models import ModelSpec
from reduction.rig_time import list_time as acquisition_time
from reduction.whirl import Directions
from rigunits import HZ

RUNOUT_KEEP_AWAY = 0.1  # ratios within this of Omega/omega = 1 are not proposed (a matrix's are warned)
SYNCHRONOUS_REFUSAL = 0.01
"""A measured orbit ratio r with ||r| - 1| below this is refused (a matrix's [orbit] list,
static or a sequential point's initial list). The spindle's 1x runout is locked to the spin:
at r = 1 it has the orbit's frequency and the same phase in every orbit revolution, so
averaging a block's revolutions keeps it whole and the runout fit (reduction.runout, which
finds its phase from how it turns through the revolutions) has nothing to go on; within 0.01
of 1 it turns by about half a turn or less over 50 revolutions, and what is left biases the
coefficients (C by 12-18 % at r = 1 on the simulator). Between this and RUNOUT_KEEP_AWAY the
ratios are kept, with a warning: the paper's own list has 0.978 and 1.089."""
GRID_STEP = 0.05  # ratio step of the search grid
MAX_PASSES = 20  # exchange passes (each tries every position against every grid point)


@dataclass(frozen=True)
class DesignProblem:
    """What a list is judged on (SI): the model, prior coefficients theta (column order of
    ``spec``), spin omega (rad/s), orbit radius (m), per-revolution noise u (4,) of x, y
    (m), fx, fy (N), revolutions averaged per block, whirl directions of every frequency."""

    spec: ModelSpec
    theta: np.ndarray
    spin: float
    radius: float
    u_revolution: np.ndarray
    revolutions: int = 50
    directions: Directions = Directions.BOTH
    scales: np.ndarray | None = None  # (p,) what "relative" divides by; None: coefficient_scales
    noise_ratios: np.ndarray | None = None  # (m,) ratios where u_revolution (m, 4) was measured

    def __post_init__(self) -> None:
        object.__setattr__(self, "directions", Directions(self.directions))

    def noise_at(self, ratios: ArrayLike) -> FloatArray:
        """(n, 4) per-revolution noise at ``ratios``: the stated (4,), or the measured
        (m, 4) interpolated linearly in the ratio (held constant beyond the ends)."""
        r = np.asarray(ratios, dtype=float)
        u = np.asarray(self.u_revolution, dtype=float)
        if self.noise_ratios is None:
            stated: FloatArray = np.broadcast_to(u, (r.size, 4)).copy()
            return stated
        order = np.argsort(self.noise_ratios)
        nr, u = np.asarray(self.noise_ratios, dtype=float)[order], u[order]
        return np.stack([np.interp(r, nr, u[:, c]) for c in range(4)], axis=1)


@dataclass(frozen=True)
class ListPrediction:
    """Predicted standard errors of one list (ratios ascending); ``worst`` is the largest
    relative standard error (a fraction; inf when the list cannot identify the model), and
    ``refusal`` then says why (the coefficients left undetermined)."""

    ratios: tuple[float, ...]
    std_errors: np.ndarray | None  # (p,) SI, column order of the spec; None: not identifiable
    relative: np.ndarray | None  # (p,) fractions
    worst: float
    refusal: str | None = None  # why the list cannot identify the model; None when it can


@dataclass(frozen=True)
class Proposal:
    """The proposed list, whether it reached the target (None without one), and how many
    lists were evaluated on the way."""

    best: ListPrediction
    target: float | None
    reached: bool | None
    evaluated: int


def coefficient_scales(spec: ModelSpec, theta: ArrayLike, spin: float) -> FloatArray:
    """(p,) size of each coefficient's matrix: RMS of the constant term's diagonal at theta,
    divided by spin^order (SI). A matrix whose diagonal is zero gets scale 1."""
    values = np.asarray(theta, dtype=float)
    diag: dict[str, list[float]] = {}
    for j, t in enumerate(spec.terms):
        if t.order == 0 and t.entries[0][0] == t.entries[0][1]:
            diag.setdefault(t.matrix, []).append(values[j])
    out = np.empty(spec.n_coefficients)
    for j, t in enumerate(spec.terms):
        size = float(np.sqrt(np.mean(np.square(diag.get(t.matrix, [0.0])))))
        out[j] = (size if size > 0 else 1.0) / spin**t.order
    return out


def predict(
    problem: DesignProblem,
    ratios: ArrayLike,
    revolutions: ArrayLike | None = None,
    whirl: Sequence[Directions] | None = None,
) -> ListPrediction:
    """Predicted (Cramer-Rao) standard errors of the list ``ratios`` (|Omega|/omega), each
    block averaging ``problem.revolutions``, or ``revolutions`` (one per ratio, in the order
    of ``ratios``, both directions alike); each ratio in ``problem.directions``, or in its
    entry of ``whirl`` (one per ratio, in the order of ``ratios``: a ratio may then be there
    twice, once per direction)."""
    order = np.argsort(np.asarray(ratios, dtype=float), kind="stable")
    r = tuple(float(np.asarray(ratios, dtype=float)[i]) for i in order)
    n = (
        np.full(len(r), float(problem.revolutions))
        if revolutions is None
        else np.asarray(revolutions, dtype=float)[order]
    )
    ways = [problem.directions] * len(r) if whirl is None else [Directions(whirl[i]) for i in order]
    hz = np.asarray(r) * problem.spin / HZ
    orbit, x, y = design_orbits(hz, ways, problem.radius)
    per = [w.blocks for w in ways]
    u = problem.noise_at(orbit / problem.spin) / np.sqrt(np.repeat(n, per))[:, None]
    what = f"the list (ratios {', '.join(f'{v:.10g}' for v in r)})"
    if 4 * orbit.size < problem.spec.n_coefficients:  # fewer equations than coefficients
        few = f"{what} has {4 * orbit.size} real equations, too few for {problem.spec.n_coefficients} coefficients"
        return ListPrediction(r, None, None, float("inf"), few)
    try:
        cov = predicted_covariance(problem.spec, orbit, x, y, u, problem.theta, what)
    except ReductionError as err:  # IdentifiabilityError: the rank rule of identify
        return ListPrediction(r, None, None, float("inf"), str(err))
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    scales = problem.scales
    if scales is None:
        scales = coefficient_scales(problem.spec, problem.theta, problem.spin)
    rel = se / scales
    return ListPrediction(r, se, rel, float(np.max(rel)))


def smooth_noise(ratios: ArrayLike, u_revolution: ArrayLike) -> FloatArray:
    """(m, 4) per-revolution noise measured at ``ratios`` (m,), smoothed: per channel a
    straight line in the ratio through log u (least squares; the mean with fewer than three
    ratios). One block's noise figure scatters by about 1/sqrt(2 n); a design that trusted
    each ratio's own figure would pick the ratios whose noise happened to come out low."""
    r = np.asarray(ratios, dtype=float)
    u = np.asarray(u_revolution, dtype=float)
    if not np.all(np.isfinite(u) & (u > 0)):
        raise ReductionError("smooth_noise: every noise figure must be finite and > 0")
    logu = np.log(u)
    if r.size < 3 or np.ptp(r) == 0:
        mean: FloatArray = np.exp(np.broadcast_to(np.mean(logu, axis=0), logu.shape)).copy()
        return mean
    coef = np.polyfit(r, logu, 1)  # (2, 4)
    line: FloatArray = np.exp(np.outer(r, coef[0]) + coef[1])
    return line


def near_one(ratios: ArrayLike, distance: float) -> np.ndarray:
    """True (per ratio) where |ratio| is closer than ``distance`` to Omega/omega = 1; a ratio at
    ``distance`` (to rounding: 0.9 and 1.1 at 0.1) is not."""
    close: np.ndarray = np.abs(np.abs(np.asarray(ratios, dtype=float)) - 1.0) < distance - 1e-9
    return close


def runout_stays(ratios: ArrayLike, revolutions: ArrayLike) -> np.ndarray:
    """True (per ratio) where the spin's 1x tone (runout, unbalance) turns less than one whole
    turn against the orbit over a block of ``revolutions``: revolutions x |1/|ratio| - 1| < 1.
    Such a tone stays in the block's mean phasor and in neither its scatter nor its stated
    uncertainty u (docs/orbit-table.md: u near Omega/omega = 1), so u understates the error."""
    r = np.abs(np.asarray(ratios, dtype=float))
    stays: np.ndarray = np.asarray(revolutions, dtype=float) * np.abs(1.0 / r - 1.0) < 1.0
    return stays


def allowed_ratios(lo: float, hi: float, step: float = GRID_STEP, keep_away: float = RUNOUT_KEEP_AWAY) -> np.ndarray:
    """Grid of ratios in [lo, hi] (multiples of ``step``) at least ``keep_away`` from 1."""
    if not 0 < lo < hi:
        raise ReductionError(f"allowed_ratios: need 0 < lo < hi, got {lo:g}, {hi:g}")
    k = np.arange(np.ceil(lo / step - 1e-9), np.floor(hi / step + 1e-9) + 1)
    grid = np.round(k * step, 10)
    grid = np.asarray(grid[~near_one(grid, keep_away)], dtype=float)
    if grid.size == 0:
        raise ReductionError(f"no orbit ratio in [{lo:g}, {hi:g}] stays {keep_away:g} away from 1")
    return grid


def best_list(
    problem: DesignProblem,
    grid: ArrayLike,
    count: int,
    score: Callable[[ListPrediction], float] | None = None,
) -> tuple[ListPrediction, int]:
    """The exchange algorithm's best list of ``count`` distinct grid ratios (and how many
    lists it evaluated); ``score(prediction) -> float`` is minimised, default the worst
    relative standard error."""
    judge = score or (lambda pred: pred.worst)
    ratios = np.unique(np.asarray(grid, dtype=float))
    if not 1 <= count <= ratios.size:
        raise ReductionError(f"best_list: {count} frequencies from a grid of {ratios.size}")
    picks = [int(i) for i in np.unique(np.round(np.linspace(0, ratios.size - 1, count)).astype(int))]
    picks += [i for i in range(ratios.size) if i not in picks][: count - len(picks)]
    best = predict(problem, ratios[picks])
    best_score, evaluated = judge(best), 1
    for _ in range(MAX_PASSES):
        improved = False
        for pos in range(count):
            for g in range(ratios.size):
                if g in picks:
                    continue
                trial = picks[:pos] + [g] + picks[pos + 1 :]
                pred = predict(problem, ratios[trial])
                evaluated += 1
                s = judge(pred)
                if s < best_score * (1 - 1e-9):
                    best, best_score, picks, improved = pred, s, trial, True
        if not improved:
            break
    return best, evaluated


def time_to_target(
    problem: DesignProblem, prediction: ListPrediction, target: float, *, block_overhead: float = 0.0
) -> float:
    """Predicted rig time (s) of a list whose blocks average just enough revolutions
    (:func:`revolutions_for`) to reach ``target`` (reduction.rig_time: trigger revolution
    included), plus ``block_overhead`` s per block."""
    n = revolutions_for(prediction, problem.revolutions, target)
    if n is None:
        return float("inf")
    blocks = len(prediction.ratios) * problem.directions.blocks
    return acquisition_time(prediction.ratios, problem.spin, n, problem.directions) + blocks * block_overhead


def propose(
    problem: DesignProblem,
    grid: ArrayLike,
    *,
    count: int | None = None,
    target: float | None = None,
    block_overhead: float = 0.0,
) -> Proposal:
    """Best list of ``count`` frequencies (lowest worst relative standard error), or, with
    ``target`` (a fraction), the list that reaches it in the least rig time: for every
    count, the list minimising :func:`time_to_target`; the cheapest count wins, so a
    per-block overhead favours fewer frequencies. ``reached`` says whether the stated
    ``problem.revolutions`` already reach the target (else :func:`revolutions_for` says
    how many the blocks need)."""
    ratios = np.unique(np.asarray(grid, dtype=float))
    if target is None:
        if count is None:
            raise ReductionError("propose: give a count or a target")
        best, n = best_list(problem, ratios, min(count, ratios.size))
        return Proposal(best, None, None, n)
    if not target > 0:
        raise ReductionError(f"propose: target must be > 0, got {target:g}")

    def cost(pred: ListPrediction) -> float:
        return time_to_target(problem, pred, target, block_overhead=block_overhead)

    total, cheapest, best_cost = 0, None, float("inf")
    top = ratios.size if count is None else min(count, ratios.size)
    for k in range(max(1, min(problem.spec.min_frequencies, top)), top + 1):
        pred, n = best_list(problem, ratios, k, score=cost)
        total += n
        if cost(pred) < best_cost:
            cheapest, best_cost = pred, cost(pred)
    if cheapest is None:
        cheapest = pred
    return Proposal(cheapest, target, cheapest.worst <= target, total)


def revolutions_for(prediction: ListPrediction, revolutions: int, target: float) -> int | None:
    """Revolutions per block that bring the list's worst relative standard error to
    ``target`` (variance ~ 1/n); None when the list cannot identify the model."""
    if prediction.relative is None:
        return None
    return max(1, int(np.ceil(revolutions * (prediction.worst / target) ** 2)))
