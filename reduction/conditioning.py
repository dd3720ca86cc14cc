"""Is an identifiable fit well conditioned: the warning of :func:`ill_conditioning`.

It compares the condition number of the column-scaled regression with that of the same
frequencies on the ideal design with both whirl directions
(:func:`reduction.design.reference_design`) and warns, naming the poorly determined
coefficients, when the ratio exceeds ``ILL_CONDITIONED_RATIO`` (100: a hundredfold
amplification of relative data errors beyond what the frequencies themselves impose), or when
a standard error exceeds ``MAX_SE_INFLATION`` times that of the yardstick design.
"""

from __future__ import annotations

import numpy as np

from reduction.arrays import FloatArray
from reduction.design import YARDSTICK_SPAN, reference_design, yardstick_design
from reduction.memo import DESIGN_MEMO_ROWS, DesignMemo
from reduction.models import ModelSpec
from reduction.rank import Rank, design_rank
from reduction.table import OrbitTable
from reduction.whirl import Directions

ILL_CONDITIONED_RATIO = 100.0  # warn when cond(table) > 100 x cond(same frequencies, ideal design)
MAX_SE_INFLATION = 10.0  # warn when a standard error is > 10 x that of the yardstick design (variance 100 x)
WEAK_LISTED = 8
_YARDSTICKS: DesignMemo[tuple[Rank, Rank, Directions, int]] = DesignMemo(32)  # ill_conditioning's


def ill_conditioning(spec: ModelSpec, table: OrbitTable, rank: Rank) -> str | None:
    """The warning for an identifiable but ill-conditioned fit, or None.

    Relative test: the table's column-scaled condition number (``rank``) against that of the
    same distinct frequencies on the ideal design with both whirl directions, flagged above
    ``ILL_CONDITIONED_RATIO`` times it. Absolute test (v3): each coefficient's variance
    inflation (diag of the column-scaled (A^T A)^-1) against the yardstick design
    (:func:`reduction.design.yardstick_design`), flagged when a standard error is inflated
    above ``MAX_SE_INFLATION``. The coefficients inflated most (at least a tenth of the
    worst and above the ratio's square root) are named.
    """
    forward = table.forward()
    directions = (
        Directions.BOTH
        if forward.any() and not forward.all()
        else Directions.FORWARD
        if forward.all()
        else Directions.BACKWARD
    )
    ref, yard, directions, n_yard = _yardsticks(spec, np.asarray(table.orbit, dtype=float), directions)
    cond, cond_ref = rank.condition_number, ref.condition_number
    relative = bool(np.isfinite(cond_ref) and cond > ILL_CONDITIONED_RATIO * cond_ref)
    factors = _variance_factors(rank)
    absolute = np.sqrt(factors / _variance_factors(yard))
    if not relative and not np.max(absolute) > MAX_SE_INFLATION:
        return None
    inflation = np.maximum(np.sqrt(factors / _variance_factors(ref)) if relative else 0.0, absolute)
    order = np.argsort(-inflation)
    weak = [
        spec.names[j] for j in order if inflation[j] >= max(0.1 * inflation[order[0]], np.sqrt(ILL_CONDITIONED_RATIO))
    ]
    weak = weak or [spec.names[order[0]]]
    listed = ", ".join(weak[:WEAK_LISTED]) + (f" and {len(weak) - WEAK_LISTED} more" if len(weak) > WEAK_LISTED else "")
    return (
        f"ill-conditioned: condition number {cond:.3g}, {cond / cond_ref:.3g} times that of the same "
        f"frequencies with forward and backward circular orbits ({cond_ref:.3g}; orbitrig warns above "
        f"{ILL_CONDITIONED_RATIO:g} times); standard errors up to {np.max(absolute):.3g} times those of "
        f"{'forward and backward' if directions is Directions.BOTH else directions} circles at {n_yard} frequencies spread over 1/{YARDSTICK_SPAN:g} .. 1 of the "
        f"highest (orbitrig warns above {MAX_SE_INFLATION:g} times); poorly determined: {listed}. Forward "
        "and backward whirl of similar size at well separated frequencies would determine them."
    )


def _yardsticks(spec: ModelSpec, orbit: FloatArray, directions: Directions) -> tuple[Rank, Rank, Directions, int]:
    """(reference, yardstick Rank, its directions, its frequency count) of :func:`ill_conditioning`:
    functions of the orbit frequencies and whirl directions, memoised up to ``DESIGN_MEMO_ROWS`` rows."""

    def compute() -> tuple[Rank, Rank, Directions, int]:
        ref = design_rank(spec, *reference_design(orbit), 0.0)
        yard_design = yardstick_design(orbit, spec.min_frequencies, directions)
        yard, used = design_rank(spec, *yard_design), directions
        if yard.deficiency:  # the table's one direction cannot identify the model: judge against both
            used = Directions.BOTH
            yard_design = yardstick_design(orbit, spec.min_frequencies, used)
            yard = design_rank(spec, *yard_design)
        return ref, yard, used, len(np.unique(yard_design[0]))

    if orbit.size > DESIGN_MEMO_ROWS:
        return compute()
    return _YARDSTICKS.get((spec.terms, orbit.tobytes(), directions), compute)


def _variance_factors(rank: Rank) -> np.ndarray:
    """diag((A_s^T A_s)^-1) of the column-scaled regression (unit-noise variance factors)."""
    s = rank.singular_values[: rank.n_columns]
    with np.errstate(divide="ignore"):
        factors: FloatArray = np.sum((rank.vt.T / s) ** 2, axis=1)
    return factors
