"""What the report says about each identification beyond its coefficients (orbit-table v2):
intervals and the uncertainty budget, the model-adequacy verdict, the derived quantities,
and the simulator's true impedance. Numbers come from reduction's pure functions applied
to the repeated identifications, or from the stored identification where it holds them.

SI inside (N/m, N s/m, kg, rad/s); the page and the figures convert at the edge.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from orbitrig.analysis.reduce import Reduced, identify_point
from orbitrig.load_systems import LoadSystem
from orbitrig.store.fit_record import expanded_k, expanded_ks
from reduction.adequacy import Adequacy, frequency_dependence
from reduction.combined_dof import part_coverage
from reduction.derived import Derived, derived_quantities
from reduction.errors import ReductionError
from reduction.models import CONSTANT, is_constant
from reduction.statistics import Interval
from reduction.table import OrbitTable
from reduction.lms_comparison import LmsAgreement, lms_agreement
from reduction.systematic import (
    Calibration,
    UncertaintyBasis,
    combined_covariance,
    systematic_jacobian,
)

#: the budget columns a stored identification may carry under "uncertainty" (SI std per key)
BUDGET_PARTS = ("statistical", "systematic", "combined", "expanded")


@dataclass(frozen=True)
class CoefficientRow:
    """One coefficient of one identification, SI; None where the run does not state it."""

    key: str
    value: float
    std: float | None  # statistical standard uncertainty (the fit's standard error)
    interval: tuple[float, float] | None  # 95 % interval, of the fit's kind (interval_kind)
    systematic: float | None  # type B standard uncertainty (calibration)
    expanded: float | None  # combined expanded uncertainty U = k u_c
    k: float | None  # its coverage factor (orbitrig.store.fit_record.expanded_ks: Student's t at its effective dof)


def coefficient_rows(r: Reduced) -> list[CoefficientRow]:
    """Rows of one identification in the identification's key order."""
    ident = r.identification
    budget = (r.stored or {}).get("uncertainty") or {}
    sys_u, expanded = budget.get("systematic") or {}, budget.get("expanded") or {}
    ks = expanded_ks(r.stored or {}) if expanded else {}
    rows = []
    for key, value in ident.coefficients.items():
        ci = ident.confidence_95.get(key)
        rows.append(
            CoefficientRow(
                key,
                value,
                ident.std_errors.get(key),
                None if ci is None else (float(ci[0]), float(ci[1])),
                sys_u.get(key),
                expanded.get(key),
                ks.get(key),
            )
        )
    return rows


#: each kind of 95 % interval: the table column's name, and the sentence of the page's units note
INTERVAL_TEXT = {
    Interval.NORMAL: (
        "normal, 1.96",
        "normal quantile 1.96 where the orbit table states the phasor uncertainties (known covariance)",
    ),
    Interval.STUDENT_T: (
        "Student t, 4n \u2212 p dof",
        "Student t with 4n \u2212 p degrees of freedom where the covariance is estimated from the residuals",
    ),
}


def interval_kind(r: Reduced) -> Interval:
    """Where the 95 % interval of `r`'s identification takes its quantile (its own ``interval``)."""
    return Interval(str(r.identification.interval))


def interval_sentence(results: list[Reduced]) -> str:
    """The page's statement of the 95 % intervals of `results` (statistical only): each kind they
    use, in words (a clause of the page's units note, which goes on after it: no closing period)."""
    kinds = dict.fromkeys(interval_kind(r) for r in results if r.identification is not None)
    if not kinds:
        return "95 % interval: none identified"
    return "95 % interval, statistical only (standard errors, no calibration uncertainty): " + "; ".join(
        INTERVAL_TEXT[k][1] for k in kinds
    )


def has_budget(results: list[Reduced]) -> bool:
    """True when any of `results` was stored with its systematic budget."""
    return any((r.stored or {}).get("uncertainty") for r in results)


#: how the page states the k of a combined U
COMBINED_K = (
    "k of each coefficient Student's t at 95.45 % at the Welch-Satterthwaite effective degrees of "
    "freedom of its statistical part (infinite with u_* columns, else 4n \u2212 p) and each calibration "
    "fit's part (its record's dof), 2 where every part is known exactly"
)


def dof_notes(results: list[Reduced]) -> list[str]:
    """What the runs' budgets say of calibration parts whose dof the record did not state (each once)."""
    notes = (((r.stored or {}).get("uncertainty") or {}).get("dof_notes") or [] for r in results)
    return list(dict.fromkeys(n for ns in notes for n in ns))


def warnings_of(r: Reduced) -> list[str]:
    """The identification's warnings: the repeated fit's, and the stored ones it does not repeat."""
    out = list(r.identification.warnings) if r.identification is not None else []
    out += [w for w in (r.stored or {}).get("warnings") or [] if w not in out]
    return out


@dataclass(frozen=True)
class Verdict:
    """Model adequacy of one frequency-dependent fit against the constant fit of its model."""

    lms: LoadSystem
    dependent: Reduced
    adequacy: Adequacy | None
    error: str | None = None

    @property
    def text(self) -> str:
        return self.adequacy.verdict if self.adequacy is not None else f"adequacy not tested: {self.error}"


def adequacy_verdicts(lms: LoadSystem, results: list[Reduced]) -> list[Verdict]:
    """Every frequency-dependent fit of `results` tested against the constant fit of the same
    model and method (repeated here when the run did not ask for it)."""
    out = []
    for dep in (r for r in results if not is_constant(r.freq_dep)):
        const = next(
            (r for r in results if (r.model, r.method) == (dep.model, dep.method) and is_constant(r.freq_dep)), None
        )
        if const is None:
            const = identify_point(dep.point, lms, dep.model, CONSTANT.text, dep.method)
        if const.identification is None:
            out.append(Verdict(lms, dep, None, f"the constant {dep.model} was refused: {const.error}"))
            continue
        try:
            out.append(Verdict(lms, dep, frequency_dependence(const.identification, dep.identification)))
        except ReductionError as err:
            out.append(Verdict(lms, dep, None, str(err)))
    return out


@dataclass(frozen=True)
class LmsComparison:
    """The two systems' comparison of one model the page shows: ``agreement`` (E_n in 1, the
    joint chi2 test), its uncertainty ``basis``, and whether it is the one the sweep stored
    (``stored``) or was repeated here with the statistical uncertainties (no stored one)."""

    agreement: LmsAgreement
    basis: UncertaintyBasis
    stored: bool


def lms_comparison(a: Reduced, b: Reduced) -> LmsComparison | None:
    """The sweep's stored comparison of `a` and `b` (orbit-table ``lms_consistency``: E_n and the
    chi2 test on the uncertainties the sweep had, combined where the rig stated a calibration
    uncertainty), else :func:`lms_normalised_difference` repeated here; None when neither exists."""
    c = (a.stored or {}).get("lms_consistency") or {}
    if "chi2" in c and "error" not in c:
        e_n = {k: _finite(v) for k, v in c["e_n"].items()}
        chi2, limit, p = (_finite(c[k]) for k in ("chi2", "limit", "p_value"))
        ag = LmsAgreement(e_n, chi2, int(c["dof"]) if chi2 is not None else 0, float(c["level"]), limit, p)
        return LmsComparison(ag, UncertaintyBasis(c["basis"]), stored=True)
    repeated = lms_normalised_difference(a, b)
    return None if repeated is None else LmsComparison(repeated, UncertaintyBasis.STATISTICAL, stored=False)


def _finite(v) -> float | None:
    return None if v is None or not np.isfinite(v) else float(v)


def lms_normalised_difference(a: Reduced, b: Reduced) -> LmsAgreement | None:
    """E_n = (a - b) / u(a - b) of each coefficient of one model identified from two load
    measuring systems and their joint chi2 test at the family-wise 5 % level, repeated from the
    fits with their statistical uncertainties only (the run's calibration budget is the
    sweep's: :func:`lms_comparison` uses its stored result); None when the two fits are not of
    one model."""
    try:
        return lms_agreement(
            a.identification,
            a.point.tables[a.lms],
            b.identification,
            b.point.tables[b.lms],
            Calibration(),
            Calibration(),
        )
    except (ReductionError, KeyError):
        return None


def orbit_grid(orbit: np.ndarray, n: int = 120) -> np.ndarray:
    """Omega grid (rad/s, > 0) over the tested range of |Omega|."""
    w = np.abs(np.asarray(orbit, dtype=float))
    w = w[np.isfinite(w) & (w > 0)]
    return np.linspace(w.min(), w.max(), n) if w.size else np.array([])


def derived_basis(r: Reduced) -> UncertaintyBasis:
    """The covariance the derived quantities of `r` rest on, as the exports': COMBINED where the
    run stored its budget (with the calibration parameters' stated std), else STATISTICAL."""
    u = (r.stored or {}).get("uncertainty") or {}
    return UncertaintyBasis.COMBINED if _has_sources(u) else UncertaintyBasis.STATISTICAL


def derived_k(r: Reduced) -> float:
    """k of the expanded uncertainty U of `r`'s results (orbitrig.store.fit_record.expanded_k of the
    stored result: the largest of its coefficients' k; of its own interval and dof when the run
    stored none: Student's t without u columns): the page's table of derived quantities, the
    derived figure's bands and zero crossings, and the n.d. note's k where no row states its own.
    A derived quantity mixes the coefficients' parts, so its own effective dof is not stored: the
    largest k (the fewest dof of any coefficient) is the conservative choice among them; a quantity
    whose calibration share exceeds every coefficient's could have fewer still (Welch-Satterthwaite's
    bound: the smallest dof of any part), which is not computed."""
    ident = r.identification
    return expanded_k(r.stored or {"interval": str(ident.interval), "dof": ident.dof})


def _has_sources(budget: dict[str, Any]) -> bool:
    return bool(budget.get("sources") and budget.get("source_std"))


def budget_covariance(ident: Any, table: OrbitTable, budget: dict[str, Any]) -> np.ndarray | None:
    """The combined covariance (SI) of ``ident`` fitted to ``table``: its own plus the calibration
    part of a stored budget's parameters (``sources``, their stated ``source_std``; its
    ``runout_covariance`` when stored and of this fit's shape: another fit made here from its
    orbit table goes without it, :func:`runout_left_out` says so); None without them or without the fit's covariance.
    ReductionError when they are not this fit's."""
    if not _has_sources(budget):
        return None
    sigma = np.asarray(budget["source_std"], dtype=float)
    return combined_covariance(ident, table, list(budget["sources"]), sigma, _own_runout(ident, budget))


def budget_coverage(ident: Any, table: OrbitTable, budget: dict[str, Any]) -> dict[str, float] | None:
    """k per coefficient of ``ident``'s combined U on a stored budget's calibration parameters, as
    the sweep takes it (reduction.combined_dof.part_coverage: each source at its stored
    ``source_dof``, the runout at ``runout_dof`` when it is this fit's); None for a budget stored
    without ``source_dof`` (before it was) or without its sources."""
    dofs = budget.get("source_dof")
    if not _has_sources(budget) or not dofs or len(dofs) != len(budget["sources"]):
        return None
    labels, J = systematic_jacobian(ident, table)
    if labels != list(budget["sources"]):
        raise ReductionError("calibration parameters do not match the Jacobian's")
    dof = {n: math.inf if v is None else float(v) for n, v in zip(labels, dofs)}
    runout_dof = budget.get("runout_dof")
    runout = (_own_runout(ident, budget), math.inf if runout_dof is None else float(runout_dof))
    return part_coverage(ident, J, labels, np.asarray(budget["source_std"], dtype=float), dof, runout)[1]


def _stored_runout(budget: dict[str, Any]) -> np.ndarray:
    """The budget's stored runout covariance ((0, 0) when it has none)."""
    return np.asarray(budget.get("runout_covariance") or np.zeros((0, 0)), dtype=float)


def _own_runout(ident: Any, budget: dict[str, Any]) -> np.ndarray | None:
    """The budget's stored runout covariance when it is of ``ident``'s shape (p x p), else None."""
    runout, p = _stored_runout(budget), len(ident.spec.names)
    return runout if runout.shape == (p, p) else None


def runout_left_out(ident: Any, budget: dict[str, Any]) -> str | None:
    """The fit warning of a fit made here whose combined covariance (:func:`budget_covariance`)
    goes without the stored budget's runout term (its covariance is the stored fit's, of another
    shape: the runout's change of x, y is not stored, so it cannot be propagated through this
    fit); None when the budget has no runout term or it is this fit's."""
    runout = _stored_runout(budget)
    if not _has_sources(budget) or runout.size == 0 or _own_runout(ident, budget) is not None:
        return None
    return (
        "U without the subtracted runout's uncertainty (type B, in the run's U of its stored fits): "
        f"its covariance is stored for a fit of {runout.shape[0]} coefficients, not for this fit's "
        f"{len(ident.spec.names)}"
    )


@dataclass(frozen=True)
class Band:
    """The covariance (free coefficients, SI) a figure draws one identification's uncertainty
    from, and what it rests on."""

    covariance: np.ndarray | None
    basis: UncertaintyBasis


def band_of(r: Reduced) -> Band:
    """The combined covariance (statistical and calibration, repeated from the stored budget's
    calibration parameters, as the tables' U) where the run stored a budget that fits, else the
    fit's statistical one."""
    try:
        cov = budget_covariance(r.identification, r.point.tables[r.lms], (r.stored or {}).get("uncertainty") or {})
    except ReductionError:
        cov = None
    if cov is not None:
        return Band(cov, UncertaintyBasis.COMBINED)
    return Band(r.identification.covariance, UncertaintyBasis.STATISTICAL)


def derived_of(r: Reduced, orbit: np.ndarray, band: Band | None = None) -> Derived | None:
    """C_eff, H forward/backward and WFR of one identification over the tested Omega range, on
    the covariance of :func:`derived_basis` (``band``, :func:`band_of` when not given); None
    when it cannot be formed (e.g. no orbit, or a stored budget that does not fit the fit)."""
    grid = orbit_grid(orbit)
    if grid.size == 0:
        return None
    band = band_of(r) if band is None else band
    if band.basis != derived_basis(r):  # the stored budget does not fit: no figure on another basis
        return None
    cov = band.covariance if band.basis == UncertaintyBasis.COMBINED else None
    try:
        return derived_quantities(r.identification, grid, r.point.settings.spin, cov=cov)
    except ReductionError:
        return None


@dataclass(frozen=True)
class TrueImpedance:
    """The simulator's impedance at the tested frequencies: ``orbit`` |Omega| rad/s (n,),
    ``z`` (n, 2, 2) complex N/m; ``exact`` when the run stored the true Z itself, else it is
    K + i|Omega| C - Omega^2 D of the stored truth rows (the simulator's reference fit)."""

    orbit: np.ndarray
    z: np.ndarray
    exact: bool

    @property
    def label(self) -> str:
        return "true Z (simulator)" if self.exact else "simulator's K, C, D (reference fit)"


def true_impedance(truth: dict | None) -> TrueImpedance | None:
    """The stored true Z per frequency (``Z_re``/``Z_im``), else Z of the stored truth K, C, D rows."""
    if not truth or not truth.get("orbit"):
        return None
    w = np.abs(np.asarray(truth["orbit"], dtype=float))
    exact = truth.get("Z_re") is not None and truth.get("Z_im") is not None
    if exact:
        z = np.asarray(truth["Z_re"], dtype=float) + 1j * np.asarray(truth["Z_im"], dtype=float)
    elif all(truth.get(m) is not None for m in "KCD"):
        k, c, d = (np.asarray(truth[m], dtype=float) for m in "KCD")
        z = k + 1j * w[:, None, None] * c - (w**2)[:, None, None] * d
    else:
        return None
    if z.shape != (w.size, 2, 2):
        return None
    return TrueImpedance(w, z, exact)
