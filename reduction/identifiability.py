"""Identifiability of an impedance regression, checked before solving.

The regression A theta = b (4 real equations per orbit frequency, see
:mod:`reduction.impedance`) is column-scaled to unit column norms; its numerical rank is
the number of singular values above ``rtol * sigma_max``. A rank below the number of
coefficients means some directions v in coefficient space leave every force unchanged
(A v = 0): the coefficients along v cannot be separated. Each such direction is named in
coefficient names, in a reduced (row-echelon) basis, with the coefficients in their own
units: e.g. forward-whirl-only circular orbits with power:1 give ``Kxx_1 - Cxy`` (only
Kxx_1 + Cxy is determined), and K = K0 + Omega^2 K_2 next to an inertia term gives
``Kxx_2 + Dxx`` for every orbit (only Kxx_2 - Dxx is determined).

Identifiability is judged on the design, not on noisy numbers
(:func:`reduction.design.idealised_design`): each whirl direction's orbits are idealised to
that direction's common shape (a circle, or the mean ellipse) and the rank is checked there.
A fixed ellipse separates nothing a circle cannot, so forward-only tables of one slightly
elliptical (or noisy) orbit shape are refused like exact circles instead of being
"separated" by their imperfection (with meaningless coefficients and huge standard errors).

An identifiable fit may still be ill-conditioned: :func:`ill_conditioning` compares the
condition number of the column-scaled regression with that of the same frequencies on the
ideal design with both whirl directions (:func:`reduction.design.reference_design`) and
warns, naming the poorly determined coefficients, when the ratio exceeds
``ILL_CONDITIONED_RATIO`` (100: a hundredfold amplification of relative data errors beyond
what the frequencies themselves impose).

v3, identifiability on signal (:mod:`reduction.excitation`): a displacement direction whose
excitation is not clear of its noise carries no orbit shape; :func:`check_signal` judges the
rank on the design with such directions removed and refuses when it is deficient.

What would separate them is found by re-testing the rank with added synthetic orbits:
the same orbits whirling the other way round (x, y -> conj), more distinct frequencies,
and generic elliptical orbits (whatever remains then is structural: no data separate it).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from reduction.arrays import FloatArray
from reduction.design import YARDSTICK_SPAN, design_orbits, idealised_design, reference_design, yardstick_design
from reduction.errors import IdentifiabilityError
from reduction.excitation import SignalDesign
from reduction.memo import DESIGN_MEMO_ROWS, DesignMemo
from reduction.impedance import regression_rows
from reduction.models import AUTO_EXPONENTS, ModelSpec, model_spec, parse_freq_dep, power_spec
from reduction.rank import RANK_RTOL, Rank, design_rank, numerical_rank
from reduction.table import OrbitTable
from reduction.whirl import Directions, Whirl

MAX_LISTED = 12
ILL_CONDITIONED_RATIO = 100.0  # warn when cond(table) > 100 x cond(same frequencies, ideal design)
MAX_SE_INFLATION = 10.0  # warn when a standard error is > 10 x that of the yardstick design (variance 100 x)
WEAK_LISTED = 8
_YARDSTICKS: DesignMemo[tuple[Rank, Rank, Directions, int]] = DesignMemo(32)  # ill_conditioning's


def combinations(rank: Rank, names: list[str]) -> list[str]:
    """Name each null direction: a reduced basis, pivot coefficient first with factor 1,
    factors in the coefficients' own units (``Kxx_1 - Cxy``, ``Kxy_2 + Kyx_2 + Dxy``)."""
    M = rank.null.T.copy()  # (k, p) in scaled coordinates
    k, p = M.shape
    row = 0
    for col in range(p):
        if row == k:
            break
        piv = row + int(np.argmax(np.abs(M[row:, col])))
        if abs(M[piv, col]) < 1e-6:
            continue
        M[[row, piv]] = M[[piv, row]]
        M[row] /= M[row, col]
        for other in range(k):
            if other != row:
                M[other] -= M[other, col] * M[row]
        row += 1
    out = []
    for w in M[:row]:
        keep = np.abs(w) > 1e-7 * np.max(np.abs(w))
        theta = w / rank.scale
        lead = int(np.argmax(keep))
        theta = theta / theta[lead]
        parts = []
        for j in np.flatnonzero(keep):
            a = theta[j]
            mag = abs(a)
            factor = (
                ""
                if abs(mag - 1) < 1e-6
                else (f"{round(mag)}*" if abs(mag - round(mag)) < 1e-6 * mag else f"{mag:.4g}*")
            )
            sign = "-" if a < 0 else "+"
            parts.append((sign, factor + names[j]))
        text = parts[0][1] + "".join(f" {s} {t}" for s, t in parts[1:])
        out.append(text)
    return out


def _determined(combo: str, all_combos: list[str]) -> str | None:
    """For a two-term direction 'P - Q' whose coefficients appear in no other direction,
    the combination the data do fix ('P + Q')."""
    tokens = combo.split(" ")
    if len(tokens) != 3:
        return None
    names = {tokens[0].split("*")[-1], tokens[2].split("*")[-1]}
    for other in all_combos:
        if other is not combo and names & {t.split("*")[-1] for t in other.split(" ")}:
            return None
    flip = {"+": "-", "-": "+"}[tokens[1]]
    return f"{tokens[0]} {flip} {tokens[2]}"


def _stack(spec: ModelSpec, orbit: ArrayLike, x: ArrayLike, y: ArrayLike) -> FloatArray:
    return regression_rows(spec, orbit, x, y)


def _whirl(table: OrbitTable) -> Whirl | None:
    """The direction if every orbit is (nearly) a circle of that direction, else None."""
    a_f, a_b = table.whirl_components()
    if np.all(np.abs(a_b) <= 1e-3 * np.abs(a_f)):
        return Whirl.FORWARD
    if np.all(np.abs(a_f) <= 1e-3 * np.abs(a_b)):
        return Whirl.BACKWARD
    return None


def _extra_frequencies(table: OrbitTable, count: int) -> np.ndarray:
    lo, hi = float(np.min(table.orbit)), float(np.max(table.orbit))
    if hi <= lo * 1.05:
        lo, hi = lo * 0.5, hi * 1.5
    return np.linspace(lo, hi, count)


def analyse(spec: ModelSpec, table: OrbitTable, A: np.ndarray | None = None, rtol: float = RANK_RTOL) -> Rank:
    """Check that ``table`` identifies ``spec``; raise :class:`IdentifiabilityError` if not.

    Order of the checks: enough frequencies; the idealised design (each whirl direction at
    its common shape) has full rank; the table's own (possibly weighted) regression A has
    full rank. Returns the :class:`Rank` of the column-scaled A.
    """
    if A is None:
        A = _stack(spec, table.orbit, table.x, table.y)
    rank = numerical_rank(A, rtol)
    if table.n < spec.min_frequencies:
        raise _refusal(spec, table, A, rank, rtol, "few")
    x, y, fixed = idealised_design(table)
    ideal = table.with_phasors(x, y, table.fx, table.fy)
    ideal_rank = design_rank(spec, ideal.orbit, ideal.x, ideal.y, rtol)
    if ideal_rank.deficiency:
        A_ideal = _stack(spec, ideal.orbit, ideal.x, ideal.y)
        raise _refusal(spec, ideal, A_ideal, numerical_rank(A_ideal, rtol), rtol, "ideal" if fixed else "")
    if rank.deficiency:
        raise _refusal(spec, table, A, rank, rtol, "")
    return rank


def check_signal(spec: ModelSpec, table: OrbitTable, signal: SignalDesign, rtol: float = RANK_RTOL) -> None:
    """Raise IdentifiabilityError when ``table`` with the directions that are not clear of
    their noise removed (``signal``, :func:`reduction.excitation.signal_design`) cannot
    identify ``spec``: the rows left, idealised per whirl direction, must have full rank."""
    if not signal.changed:
        return
    keep = np.abs(signal.x) + np.abs(signal.y) > 0
    cause = "; ".join(signal.removed)
    if not np.any(keep):
        raise IdentifiabilityError(
            f"{spec.model} with freq-dep {spec.freq_dep.text} cannot be identified from this table: no "
            f"displacement is clear of its noise ({cause}); every coefficient is undetermined.",
            list(spec.names),
        )
    cleaned = table.with_phasors(signal.x, signal.y, table.fx, table.fy).subset(keep)
    if cleaned.n < spec.min_frequencies:
        raise _too_few_clear(spec, cleaned, cause)
    x, y, _ = idealised_design(cleaned)
    if design_rank(spec, cleaned.orbit, x, y, rtol).deficiency:
        A = _stack(spec, cleaned.orbit, x, y)
        rank = numerical_rank(A, rtol)
        raise _refusal(spec, cleaned.with_phasors(x, y, cleaned.fx, cleaned.fy), A, rank, rtol, "signal", cause)


def check_plan(model: str, freq_dep: str, orbit_hz: ArrayLike, directions: Directions | Sequence[Directions]) -> None:
    """Before a run: raise IdentifiabilityError when circular orbits at ``orbit_hz`` (Hz) in
    ``directions`` (one for all or one per frequency) cannot
    identify ``model`` with ``freq_dep`` (power:auto: when no exponent M can)."""
    orbit, x, y = design_orbits(orbit_hz, directions, 1.0)
    zero = np.zeros(orbit.size, dtype=complex)
    table = OrbitTable(0.0, orbit, x, y, zero, zero)
    fd = parse_freq_dep(freq_dep)
    if not fd.auto:
        analyse(model_spec(model, fd), table)
        return
    refused = {}
    for m in AUTO_EXPONENTS:
        try:
            analyse(power_spec(model, m), table)
            return
        except IdentifiabilityError as err:
            refused[m] = err
    raise IdentifiabilityError(
        f"{model} with freq-dep power:auto: no exponent M in {AUTO_EXPONENTS[0]}..{AUTO_EXPONENTS[-1]} "
        "is identifiable from the planned orbits.\n\n" + "\n\n".join(f"power:{m}: {e}" for m, e in refused.items()),
        [f"power:{m}: {c}" for m, e in refused.items() for c in e.combinations],
    )


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


def _too_few_clear(spec: ModelSpec, table: OrbitTable, cause: str) -> IdentifiabilityError:
    """Fewer rows left than the model needs once the directions not clear of their noise
    (``cause``) are taken out."""
    p = spec.n_coefficients
    head = f"{spec.model} with freq-dep {spec.freq_dep.text} ({p} coefficients) cannot be identified from this table"
    return IdentifiabilityError(
        f"{head}: the displacement is not clear of its noise in {cause}; the {table.n} rows left "
        f"are fewer than the {spec.min_frequencies} orbit frequencies {p} coefficients need.",
        list(spec.names),
    )


def _refusal(
    spec: ModelSpec, table: OrbitTable, A: FloatArray, rank: Rank, rtol: float, kind: str, cause: str = ""
) -> IdentifiabilityError:
    """kind: "few" (too few frequencies), "ideal" (the idealised one-shape-per-direction
    design is rank-deficient), "signal" (so is the design without the directions not clear
    of their noise, ``cause``) or "" (the regression itself is)."""
    p = spec.n_coefficients
    names = spec.names
    head = f"{spec.model} with freq-dep {spec.freq_dep.text} ({p} coefficients) cannot be identified from this table"
    combos = combinations(rank, names)
    lines = []
    if kind == "few":
        lines.append(
            f"{head}: too few orbit frequencies: {p} coefficients need at least {spec.min_frequencies} "
            f"orbit frequencies (4 real equations each), the table has {table.n}."
        )
    elif kind == "signal":
        lines.append(
            f"{head}: the excitation is not clear of the displacement noise in {cause} (u_x, u_y, "
            "else the residual's equivalent; at least 0.5 % of each orbit). Such a direction "
            "carries noise, not an orbit shape (e.g. a line orbit whose other axis is only probe "
            "noise); without it the regression is rank-deficient."
        )
    elif kind == "ideal":
        lines.append(
            f"{head}: the orbits of each whirl direction have one common shape (idealised to it: "
            "a circle or the mean ellipse), and on that design the regression is rank-deficient; "
            "a fixed orbit shape separates nothing a circle cannot, and the orbits' small "
            "differences in shape are imperfection and noise, which would separate the terms "
            "below only with meaningless precision."
        )
    else:
        lines.append(f"{head}: the regression is rank-deficient.")
    lines.append(
        f"The regression ({4 * table.n} real equations) has numerical rank {rank.rank} of {p} "
        f"(SVD of the column-scaled matrix, relative tolerance {rtol:g}). The forces do not change "
        "when the coefficients move along these directions, so the coefficients in each cannot be separated:"
    )
    for c in combos[:MAX_LISTED]:
        fixed = _determined(c, combos)
        lines.append(f"  {c}" + (f"   (only {fixed} is determined)" if fixed else ""))
    if len(combos) > MAX_LISTED:
        lines.append(f"  ... and {len(combos) - MAX_LISTED} more")
    lines.append("What would separate them:")
    if kind == "signal":
        lines.append(
            "  - an excitation across the orbits' main axis well above the probe noise: forward and "
            "backward circular whirl, or ellipses whose minor axis stands clear of the noise."
        )
    else:
        lines += ["  - " + h for h in _hints(spec, table, A, rank, rtol)]
    return IdentifiabilityError("\n".join(lines), combos)


def _hints(spec: ModelSpec, table: OrbitTable, A: FloatArray, rank: Rank, rtol: float) -> list[str]:
    rng = np.random.default_rng(0)
    scale = float(np.sqrt(np.mean(np.abs(table.x) ** 2 + np.abs(table.y) ** 2)) or 1.0)
    n_gen = 3 * spec.min_frequencies + 3
    w_gen = _extra_frequencies(table, n_gen)
    xg, yg = (rng.standard_normal((2, n_gen)) + 1j * rng.standard_normal((2, n_gen))) * scale
    generic = numerical_rank(_stack(spec, w_gen, xg, yg), rtol)
    mirror_rows = _stack(spec, table.orbit, np.conj(table.x), np.conj(table.y))
    mirrored = numerical_rank(np.vstack([A, mirror_rows]), rtol)
    idx = np.arange(n_gen) % table.n
    w_more = w_gen * 1.0137  # distinct from the table's
    more = np.vstack(
        [
            A,
            mirror_rows,
            _stack(spec, w_more, table.x[idx], table.y[idx]),
            _stack(spec, w_more, np.conj(table.x[idx]), np.conj(table.y[idx])),
        ]
    )
    more_rank = numerical_rank(more, rtol)
    hints = []
    structural = generic.deficiency
    if rank.deficiency > structural:
        whirl = _whirl(table)
        resolved = rank.deficiency - mirrored.deficiency
        if resolved > 0:
            if whirl:
                other = Whirl.BACKWARD if whirl is Whirl.FORWARD else Whirl.FORWARD
                hints.append(
                    f"every orbit in the table is a {whirl} circular whirl: forward plus backward whirl "
                    f"(adding {other}-whirl orbits at these frequencies) separates {resolved} of these "
                    "directions; orbits of one fixed elliptical shape would not."
                )
            else:
                hints.append(
                    f"orbits whirling the other way round at these frequencies (backward-whirl orbits "
                    f"beside forward ones, or the reverse) separate {resolved} of these directions; "
                    "orbits of the same fixed shape would not."
                )
        rest = mirrored.deficiency - more_rank.deficiency
        if rest > 0:
            distinct = len(np.unique(np.round(table.orbit, 9)))
            hints.append(
                f"more distinct orbit frequencies (the table has {distinct}, each giving at most 8 real "
                f"equations with both whirl directions) separate {rest} of these directions."
            )
        rest = more_rank.deficiency - structural
        if rest > 0:
            hints.append(f"non-circular (elliptical) orbits separate {rest} of these directions.")
    if structural:
        gen_combos = combinations(generic, spec.names)
        hints.append(
            "no orbit data can separate " + ", ".join(gen_combos) + ": these terms have the same "
            "dependence on Omega for every orbit (e.g. Omega^2 K_2 and the inertia term -Omega^2 D); "
            "use a model with fewer terms (e.g. no D matrix, or a lower order or another exponent)."
        )
    return hints
