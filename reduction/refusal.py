"""Why a model cannot be identified from a table, in words (the IdentifiabilityError's message).

Each direction v in coefficient space that leaves every force unchanged (A v = 0, on the
column-scaled regression of :mod:`reduction.impedance`) is named in coefficient names, in a
reduced (row-echelon) basis, with the coefficients in their own units: e.g. forward-whirl-only
circular orbits with power:1 give ``Kxx_1 - Cxy`` (only Kxx_1 + Cxy is determined).

What would separate them is found by re-testing the rank with added synthetic orbits:
the same orbits whirling the other way round (x, y -> conj), more distinct frequencies,
and generic elliptical orbits (whatever remains then is structural: no data separate it).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from reduction.arrays import FloatArray
from reduction.errors import IdentifiabilityError
from reduction.impedance import regression_rows
from reduction.models import ModelSpec
from reduction.rank import Rank, numerical_rank
from reduction.table import OrbitTable
from reduction.whirl import Whirl

MAX_LISTED = 12


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


def too_few_clear(spec: ModelSpec, table: OrbitTable, cause: str) -> IdentifiabilityError:
    """Fewer rows left than the model needs once the directions not clear of their noise
    (``cause``) are taken out."""
    p = spec.n_coefficients
    head = f"{spec.model} with freq-dep {spec.freq_dep.text} ({p} coefficients) cannot be identified from this table"
    return IdentifiabilityError(
        f"{head}: the displacement is not clear of its noise in {cause}; the {table.n} rows left "
        f"are fewer than the {spec.min_frequencies} orbit frequencies {p} coefficients need.",
        list(spec.names),
    )


def refusal(
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
    scale = float(np.sqrt(np.mean(np.abs(table.x) ** 2 + np.abs(table.y) ** 2)))
    if scale == 0:  # no orbit at all: no other orbit shape or frequency list would help
        return ["an orbit: every row's displacement is zero (x = y = 0), so no force depends on a coefficient."]
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
