"""Designs that keep the model test: the adequacy test's needs of an orbit-frequency list.

The paper's question at an operating point is whether the coefficients depend on the orbit
frequency (its Eq. 15/16 models; reduction.adequacy tests the constant model against a
frequency-dependent one). A list that minimises rig time for the constant model's standard
errors alone puts every revolution at two or three ratios, where no frequency dependence can
be shown. A designed list therefore keeps, besides the constant model's precision:

1. **K distinct orbit frequencies spread over the band.** In one matrix entry, Z(Omega) is a
   polynomial in Omega: K order r gives Omega^r and D order r gives Omega^(r + 2) in the real
   part, C order r gives Omega^(r + 1) in the imaginary part. The richest frequency-dependent
   model of the matrix (:func:`richest`) has ``m`` distinct powers in the fuller of the two
   parts; ``K = m + 1`` distinct |Omega| leave every entry a degree of freedom against it
   (:func:`frequencies_needed`). Spread: one ratio at least in each of K equal slices of the
   reference list's span (:func:`spread_ok`), so the list does not bunch at the ends.
2. **Power.** Every coefficient of that richest model has a predicted standard error at most
   the reference list's (the allocation is made for it), and every coefficient of the design
   model too (the counts are scaled up until both hold): the frequency-dependent terms that
   the test detects are then estimated at least as precisely as on the reference list.

Pure numerics; ratios are |Omega| / omega.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from reduction.arrays import FloatArray, NoiseAt
from reduction.errors import ReductionError
from reduction.information import identified_errors, predicted_errors
from reduction.models import AUTO_EXPONENTS, ModelSpec, model_spec, resolved_freq_dep
from reduction.rig_time import Ways
from reduction.whirl import Directions

#: a matrix without a frequency-dependent model is still designed for this one (per base model)
DEFAULT_TEST_FREQ_DEP = "poly:1"


def entry_powers(spec: ModelSpec) -> tuple[set[int], set[int]]:
    """Powers of Omega in one matrix entry of Z: (real part, imaginary part)."""
    real, imag = set(), set()
    for t in spec.terms:
        if t.matrix == "K":
            real.add(t.order)
        elif t.matrix == "D":
            real.add(t.order + 2)
        else:
            imag.add(t.order + 1)
    return real, imag


def frequencies_needed(spec: ModelSpec) -> int:
    """K: distinct orbit frequencies the adequacy test against ``spec`` needs (module doc)."""
    real, imag = entry_powers(spec)
    return max(len(real), len(imag)) + 1


def richest(models: list[tuple[str, str]]) -> ModelSpec:
    """The frequency-dependent model of (model, freq_dep) pairs that needs the most distinct
    frequencies (ties: the most coefficients); power:auto counts as its highest exponent.
    Without one, ``DEFAULT_TEST_FREQ_DEP`` of the richest base model."""
    specs = []
    for model, fd in models:
        specs.append(model_spec(model, resolved_freq_dep(fd, AUTO_EXPONENTS[-1])))
    dependent = [s for s in specs if not s.freq_dep.constant]
    if not dependent:
        if not specs:
            raise ReductionError("richest: no model given")
        base = max(specs, key=lambda s: s.n_coefficients)
        dependent = [model_spec(base.model, DEFAULT_TEST_FREQ_DEP)]
    return max(dependent, key=lambda s: (frequencies_needed(s), s.n_coefficients))


@dataclass(frozen=True)
class ModelTest:
    """What a designed list must keep for the adequacy test: the model tested against the
    constant one, K distinct frequencies, one in each of K equal slices of [lo, hi]."""

    spec: ModelSpec
    frequencies: int
    lo: float
    hi: float

    def slices(self) -> np.ndarray:
        """(K + 1,) slice edges over [lo, hi]."""
        return np.linspace(self.lo, self.hi, self.frequencies + 1)

    def reason(self) -> str:
        real, imag = entry_powers(self.spec)
        return (
            f"the adequacy test of {self.spec.model} {self.spec.freq_dep.text} against the constant model needs "
            f"at least {self.frequencies} distinct orbit frequencies ({max(len(real), len(imag))} powers of Omega "
            f"per matrix entry, plus one to test them), one at least in each of {self.frequencies} equal slices "
            f"of {self.lo:g} .. {self.hi:g}, and the reference list's standard errors of its coefficients"
        )


def model_test(models: list[tuple[str, str]], reference_ratios: ArrayLike) -> ModelTest:
    """The constraint for a matrix of ``models`` whose reference list is ``reference_ratios``."""
    spec = richest(models)
    r = np.asarray(reference_ratios, dtype=float)
    k = frequencies_needed(spec)
    if np.unique(r).size < k:
        raise ReductionError(
            f"the reference list has {np.unique(r).size} distinct ratios; the adequacy test of "
            f"{spec.model} {spec.freq_dep.text} needs {k}"
        )
    return ModelTest(spec, k, float(r.min()), float(r.max()))


def spread_ok(test: ModelTest, ratios: ArrayLike) -> bool:
    """At least K distinct ratios, one at least in each slice (edges inclusive, 1e-9 slack)."""
    r = np.unique(np.round(np.asarray(ratios, dtype=float), 9))
    if r.size < test.frequencies:
        return False
    return not empty_slices(test, r)


def empty_slices(test: ModelTest, ratios: ArrayLike) -> list[tuple[float, float]]:
    """The slices (lower, upper edge) of ``test`` with none of ``ratios`` in them (edges
    inclusive, 1e-9 slack), in order."""
    r = np.asarray(ratios, dtype=float)
    edges = test.slices()
    return [
        (float(a), float(b)) for a, b in zip(edges[:-1], edges[1:]) if not np.any((r >= a - 1e-9) & (r <= b + 1e-9))
    ]


def spread_shortfall(test: ModelTest, candidates: ArrayLike) -> str | None:
    """Why no list of ``candidates`` (the ratios a design may use) passes :func:`spread_ok`,
    in words; None when all of them together pass (then some list does: a list passes when a
    part of it does)."""
    r = np.unique(np.round(np.asarray(candidates, dtype=float), 9))
    if spread_ok(test, r):
        return None
    inside = r[(r >= test.lo - 1e-9) & (r <= test.hi + 1e-9)]
    have = ", ".join(f"{v:g}" for v in inside) if inside.size else "none of them"
    empty = empty_slices(test, r)
    where = f"none in {', '.join(f'{a:.4g} .. {b:.4g}' for a, b in empty)}" if empty else "fewer distinct ones"
    return (
        f"the {test.frequencies} slices of {test.lo:g} .. {test.hi:g} are {(test.hi - test.lo) / test.frequencies:.3g} "
        f"wide, and of the ratios a list may use only {have} in {test.lo:g} .. {test.hi:g} ({where})"
    )


@dataclass(frozen=True)
class TestedAllocation:
    """A least-rig-time list that keeps the model test: ratios ascending, revolutions per
    ratio (all its directions alike; with per-direction blocks a ratio may be there twice), predicted standard errors (SI, column order) of the design
    model (``std_errors``) and of the tested model (``test_std_errors``), and their worst
    ratio to the reference list's (<= 1 by construction)."""

    ratios: tuple[float, ...]
    revolutions: tuple[int, ...]
    std_errors: FloatArray
    test_std_errors: FloatArray
    worst: float
    test_worst: float
    whirl: tuple[Directions, ...] = ()  # per ratio its directions (per-direction blocks: one each)


def _std_errors(
    spec: ModelSpec,
    theta: FloatArray,
    spin: float,
    radius: float,
    ratios: ArrayLike,
    revolutions: ArrayLike,
    u: FloatArray,
    directions: Ways,
    what: str | None = None,
) -> FloatArray:
    """(p,) predicted standard errors (SI) of ``spec`` on the list ``ratios`` at ``revolutions``
    each; with ``what`` (the list in words) IdentifiabilityError when it cannot identify
    ``spec``, else np.inf for a coefficient it cannot (reduction.information)."""
    from reduction.allocation import revolution_information

    F = revolution_information(spec, theta, spin, radius, ratios, u, directions)
    info = np.einsum("k,kij->ij", np.asarray(revolutions, dtype=float), F)
    return predicted_errors(info) if what is None else identified_errors(info, spec, what)


def allocate_keeping_test(
    test: ModelTest,
    spec: ModelSpec,
    prior: dict[str, float],
    spin: float,
    radius: float,
    grid: ArrayLike,
    noise_at: NoiseAt,
    reference: tuple[ArrayLike, ArrayLike] | tuple[ArrayLike, ArrayLike, Ways | None],
    *,
    block_overhead: float = 0.0,
    directions: Directions = Directions.BOTH,
    min_revolutions: int = 10,
    scales: ArrayLike | None = None,
    per_direction: bool = False,
) -> TestedAllocation:
    """Revolutions per ratio of ``grid`` in the least rig time such that every coefficient of
    ``spec`` and of ``test.spec`` has at most the standard error of the ``reference`` list
    ((ratios, revolutions per ratio), or with each ratio's directions as a third item) and the
    list passes :func:`spread_ok` (ReductionError saying why when no list of ``grid`` can:
    :func:`spread_shortfall`). ``prior``: coefficient name -> value (SI; names missing, e.g. frequency-dependent terms, are 0);
    ``noise_at(ratios) -> (k, 4)`` per-revolution noise of x, y (m), fx, fy (N); ``scales``
    (p,) SI: what ``spec``'s standard errors must reach instead of the reference list's.
    The reference list runs in ``directions`` (unless it gives its own); the proposal's candidates are the grid's ratios
    in ``directions``, or with ``per_direction`` each ratio in each of its whirl directions
    as a block of its own (:func:`per_direction_grid`)."""
    from reduction.allocation import allocate

    ref_r, ref_n = (np.asarray(v, dtype=float) for v in reference[:2])
    ref_n = np.broadcast_to(ref_n, ref_r.shape)
    ref_ways = reference[2] if len(reference) > 2 and reference[2] is not None else directions
    specs = (spec, test.spec)
    thetas = [np.array([float(prior.get(n, 0.0)) for n in s.names]) for s in specs]
    what = f"the reference list (ratios {', '.join(f'{r:g}' for r in ref_r)})"
    ref_se = [
        np.asarray(scales, dtype=float)
        if k == 0 and scales is not None
        else _std_errors(s, t, spin, radius, ref_r, ref_n, noise_at(ref_r), ref_ways, what)
        for k, (s, t) in enumerate(zip(specs, thetas))
    ]
    ratios, ways = per_direction_grid(grid, directions) if per_direction else (np.asarray(grid, float), directions)
    short = spread_shortfall(test, ratios)
    if short is not None:
        raise ReductionError(f"no list of these ratios keeps the model test: {short}")
    a = allocate(
        spec,
        thetas[0],
        spin,
        radius,
        ratios,
        noise_at(ratios),
        ref_se[0],
        block_overhead=block_overhead,
        min_revolutions=min_revolutions,
        directions=ways,
        admissible=lambda r: spread_ok(test, r),
        also=[(test.spec, thetas[1], ref_se[1])],
    )
    se = [
        _std_errors(s, t, spin, radius, a.ratios, a.revolutions, noise_at(a.ratios), a.whirl)
        for s, t in zip(specs, thetas)
    ]
    worst = [float(np.max(e / r)) for e, r in zip(se, ref_se)]
    return TestedAllocation(a.ratios, a.revolutions, se[0], se[1], worst[0], worst[1], a.whirl)


def per_direction_grid(
    grid: ArrayLike, directions: Directions = Directions.BOTH
) -> tuple[FloatArray, list[Directions]]:
    """Candidates of per-direction blocks: ``grid`` once per whirl direction of ``directions``
    (forward first), and each one's direction (Omega is signed: a forward and a backward block
    at one ratio are two orbit frequencies, each its own count)."""
    r = np.asarray(grid, dtype=float)
    ways = [Directions(w.value) for w in Directions(directions).whirls]
    return np.concatenate([r] * len(ways)), [w for w in ways for _ in r]
