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

An identifiable fit may still be ill-conditioned (:mod:`reduction.conditioning`). A refusal's
message, its null directions named and what would separate them, is :mod:`reduction.refusal`'s.

v3, identifiability on signal (:mod:`reduction.excitation`): a displacement direction whose
excitation is not clear of its noise carries no orbit shape; :func:`check_signal` judges the
rank on the design with such directions removed and refuses when it is deficient.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from reduction.design import design_orbits, idealised_design
from reduction.errors import IdentifiabilityError
from reduction.excitation import SignalDesign
from reduction.impedance import regression_rows
from reduction.models import AUTO_EXPONENTS, ModelSpec, model_spec, parse_freq_dep, power_spec
from reduction.rank import RANK_RTOL, Rank, design_rank, numerical_rank
from reduction.refusal import refusal, too_few_clear
from reduction.table import OrbitTable
from reduction.whirl import Directions


def analyse(spec: ModelSpec, table: OrbitTable, A: np.ndarray | None = None, rtol: float = RANK_RTOL) -> Rank:
    """Check that ``table`` identifies ``spec``; raise :class:`IdentifiabilityError` if not.

    Order of the checks: enough frequencies; the idealised design (each whirl direction at
    its common shape) has full rank; the table's own (possibly weighted) regression A has
    full rank. Returns the :class:`Rank` of the column-scaled A.
    """
    if A is None:
        A = regression_rows(spec, table.orbit, table.x, table.y)
    rank = numerical_rank(A, rtol)
    if table.n < spec.min_frequencies:
        raise refusal(spec, table, A, rank, rtol, "few")
    x, y, fixed = idealised_design(table)
    ideal = table.with_phasors(x, y, table.fx, table.fy)
    ideal_rank = design_rank(spec, ideal.orbit, ideal.x, ideal.y, rtol)
    if ideal_rank.deficiency:
        A_ideal = regression_rows(spec, ideal.orbit, ideal.x, ideal.y)
        raise refusal(spec, ideal, A_ideal, numerical_rank(A_ideal, rtol), rtol, "ideal" if fixed else "")
    if rank.deficiency:
        raise refusal(spec, table, A, rank, rtol, "")
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
        raise too_few_clear(spec, cleaned, cause)
    x, y, _ = idealised_design(cleaned)
    if design_rank(spec, cleaned.orbit, x, y, rtol).deficiency:
        A = regression_rows(spec, cleaned.orbit, x, y)
        rank = numerical_rank(A, rtol)
        raise refusal(spec, cleaned.with_phasors(x, y, cleaned.fx, cleaned.fy), A, rank, rtol, "signal", cause)


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
    raise no_exponent(model, refused, "the planned orbits")


def no_exponent(model: str, refused: dict[int, IdentifiabilityError], source: str) -> IdentifiabilityError:
    """The refusal of power:auto when every exponent M of AUTO_EXPONENTS was `refused` (M -> its
    refusal) on `source` (the planned orbits, this table): each M's reasons and combinations."""
    return IdentifiabilityError(
        f"{model} with freq-dep power:auto: no exponent M in {AUTO_EXPONENTS[0]}..{AUTO_EXPONENTS[-1]} "
        f"is identifiable from {source}.\n\n" + "\n\n".join(f"power:{m}: {e}" for m, e in refused.items()),
        [f"power:{m}: {c}" for m, e in refused.items() for c in e.combinations],
    )
