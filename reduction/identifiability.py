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

Measured orbits are never exactly circular: an orbit whose minor whirl component is below
``CIRCULAR_TOL`` (2 %) of its major one is judged by its ideal circle too, so that noisy
forward-only circles are refused like exact ones instead of being "separated" by their
noise (with meaningless coefficients and huge standard errors).

What would separate them is found by re-testing the rank with added synthetic orbits:
the same orbits whirling the other way round (x, y -> conj), more distinct frequencies,
and generic elliptical orbits (whatever remains then is structural: no data separate it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from reduction.errors import IdentifiabilityError
from reduction.impedance import real_rows, regressors
from reduction.models import ModelSpec
from reduction.regression import column_scale
from reduction.table import OrbitTable

RANK_RTOL = 1e-7  # relative singular-value tolerance on the column-scaled regression (cond > 1e7 = deficient)
MAX_LISTED = 12
CIRCULAR_TOL = 0.02  # an orbit whose minor whirl component is below 2 % of the major is a circle


@dataclass(frozen=True)
class Rank:
    """Numerical rank of a column-scaled regression and its null space (scaled coordinates)."""

    rank: int
    n_columns: int
    singular_values: np.ndarray
    null: np.ndarray  # (p, p - rank), orthonormal, scaled coordinates
    scale: np.ndarray  # column norms c: theta = u / c

    @property
    def deficiency(self) -> int:
        return self.n_columns - self.rank

    @property
    def condition_number(self) -> float:
        s = self.singular_values
        return float(s[0] / s[-1]) if s.size and s[-1] > 0 else float("inf")


def numerical_rank(A: np.ndarray, rtol: float = RANK_RTOL) -> Rank:
    """Rank of A after column scaling: singular values > rtol * sigma_max count."""
    A_s, c = column_scale(np.asarray(A, dtype=float))
    m, p = A_s.shape
    if m < p:  # pad so that the SVD returns the whole right singular basis
        A_s = np.vstack([A_s, np.zeros((p - m, p))])
    _, s, Vt = np.linalg.svd(A_s, full_matrices=False)  # m >= p here: Vt is p x p
    tol = rtol * (s[0] if s.size else 0.0)
    rank = int(np.sum(s > tol)) if s.size and s[0] > 0 else 0
    return Rank(rank, p, s, Vt[rank:].T.copy(), c)


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
            factor = "" if abs(mag - 1) < 1e-6 else (
                f"{round(mag)}*" if abs(mag - round(mag)) < 1e-6 * mag else f"{mag:.4g}*")
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


def _stack(spec: ModelSpec, orbit, x, y) -> np.ndarray:
    return real_rows(regressors(spec, orbit, x, y))


def _whirl(table: OrbitTable) -> str:
    """'forward' / 'backward' if every orbit is (nearly) a circle of that direction, else ''."""
    a_f, a_b = table.whirl_components()
    if np.all(np.abs(a_b) <= 1e-3 * np.abs(a_f)):
        return "forward"
    if np.all(np.abs(a_f) <= 1e-3 * np.abs(a_b)):
        return "backward"
    return ""


def _extra_frequencies(table: OrbitTable, count: int) -> np.ndarray:
    lo, hi = float(np.min(table.orbit)), float(np.max(table.orbit))
    if hi <= lo * 1.05:
        lo, hi = lo * 0.5, hi * 1.5
    return np.linspace(lo, hi, count)


def analyse(spec: ModelSpec, table: OrbitTable, A: np.ndarray | None = None,
            rtol: float = RANK_RTOL) -> Rank:
    """Check that ``table`` identifies ``spec``; raise :class:`IdentifiabilityError` if not.

    A is the (possibly weighted) real regression; built from the table when omitted.
    Returns the :class:`Rank` of the column-scaled regression otherwise.
    """
    if A is None:
        A = _stack(spec, table.orbit, table.x, table.y)
    rank = numerical_rank(A, rtol)
    too_few = table.n < spec.min_frequencies
    if rank.deficiency or too_few:
        raise _refusal(spec, table, A, rank, rtol, too_few)
    ideal = ideal_circles(table)
    if ideal is not table:
        A_ideal = _stack(spec, ideal.orbit, ideal.x, ideal.y)
        ideal_rank = numerical_rank(A_ideal, rtol)
        if ideal_rank.deficiency:
            raise _refusal(spec, ideal, A_ideal, ideal_rank, rtol, False, idealised=True)
    return rank


def ideal_circles(table: OrbitTable, tol: float = CIRCULAR_TOL) -> OrbitTable:
    """``table`` with every nearly circular orbit (minor whirl component below ``tol`` times
    the major one) replaced by its ideal circle; ``table`` itself when none is."""
    a_f, a_b = table.whirl_components()
    forward = np.abs(a_f) >= np.abs(a_b)
    near = np.minimum(np.abs(a_f), np.abs(a_b)) < tol * np.maximum(np.abs(a_f), np.abs(a_b))
    near &= (np.abs(a_f) > 0) | (np.abs(a_b) > 0)
    if not np.any(near):
        return table
    major = np.where(forward, a_f, a_b)
    x = np.where(near, major, table.x)
    y = np.where(near, np.where(forward, -1j, 1j) * major, table.y)
    if np.array_equal(x, table.x) and np.array_equal(y, table.y):
        return table
    return OrbitTable(table.spin, table.orbit, x, y, table.fx, table.fy, table.gamma2)


def _refusal(spec, table, A, rank, rtol, too_few, idealised=False) -> IdentifiabilityError:
    p = spec.n_coefficients
    names = spec.names
    combos = combinations(rank, names)
    head = f"{spec.model} with freq-dep {spec.freq_dep.text} ({p} coefficients) cannot be identified from this table"
    lines = []
    if too_few:
        lines.append(
            f"{head}: too few orbit frequencies: {p} coefficients need at least {spec.min_frequencies} "
            f"orbit frequencies (4 real equations each), the table has {table.n}.")
    elif idealised:
        lines.append(
            f"{head}: the orbits are circular to within {CIRCULAR_TOL:.0%} (minor over major whirl "
            "component), and with ideal circles the regression is rank-deficient; the small "
            "non-circularity left is imperfection and noise, which would separate the terms below "
            "only with meaningless precision.")
    else:
        lines.append(f"{head}: the regression is rank-deficient.")
    lines.append(
        f"The regression ({4 * table.n} real equations) has numerical rank {rank.rank} of {p} "
        f"(SVD of the column-scaled matrix, relative tolerance {rtol:g}). The forces do not change "
        "when the coefficients move along these directions, so the coefficients in each cannot be separated:")
    for c in combos[:MAX_LISTED]:
        fixed = _determined(c, combos)
        lines.append(f"  {c}" + (f"   (only {fixed} is determined)" if fixed else ""))
    if len(combos) > MAX_LISTED:
        lines.append(f"  ... and {len(combos) - MAX_LISTED} more")
    lines.append("What would separate them:")
    lines += ["  - " + h for h in _hints(spec, table, A, rank, rtol)]
    return IdentifiabilityError("\n".join(lines), combos)


def _hints(spec, table, A, rank, rtol) -> list[str]:
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
    more = np.vstack([A, mirror_rows,
                      _stack(spec, w_more, table.x[idx], table.y[idx]),
                      _stack(spec, w_more, np.conj(table.x[idx]), np.conj(table.y[idx]))])
    more_rank = numerical_rank(more, rtol)
    hints = []
    structural = generic.deficiency
    if rank.deficiency > structural:
        whirl = _whirl(table)
        resolved = rank.deficiency - mirrored.deficiency
        if resolved > 0:
            if whirl:
                other = "backward" if whirl == "forward" else "forward"
                hints.append(
                    f"every orbit in the table is a {whirl} circular whirl: forward plus backward whirl "
                    f"(adding {other}-whirl orbits at these frequencies) separates {resolved} of these "
                    "directions; elliptical orbits would too.")
            else:
                hints.append(f"orbits whirling the other way round at these frequencies separate {resolved} of these directions.")
        rest = mirrored.deficiency - more_rank.deficiency
        if rest > 0:
            distinct = len(np.unique(np.round(table.orbit, 9)))
            hints.append(
                f"more distinct orbit frequencies (the table has {distinct}, each giving at most 8 real "
                f"equations with both whirl directions) separate {rest} of these directions.")
        rest = more_rank.deficiency - structural
        if rest > 0:
            hints.append(f"non-circular (elliptical) orbits separate {rest} of these directions.")
    if structural:
        gen_combos = combinations(generic, spec.names)
        hints.append(
            "no orbit data can separate " + ", ".join(gen_combos) + ": these terms have the same "
            "dependence on Omega for every orbit (e.g. Omega^2 K_2 and the inertia term -Omega^2 D); "
            "use a model with fewer terms (e.g. no D matrix, or a lower order or another exponent).")
    return hints
