"""One stored identification as arrays: what the Python API and every export read.

A :class:`FitRecord` holds a fit's coefficients aligned with ``names`` (SI, ``units``),
their standard error ``std`` and expanded uncertainty ``U`` (:func:`expanded_uncertainty`,
the one rule for U), the covariance with the names of its rows (the free coefficients,
which a constrained model has fewer of than ``names``), the uncertainty budget, the
adequacy test, the derived quantities and the two-LMS consistency, as the sweep stored them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from orbitrig.load_systems import LoadSystem
from reduction.statistics import coverage_factor
from reduction.systematic import UncertaintyBasis
from rigunits import coefficient_unit

if TYPE_CHECKING:
    from orbitrig.store.stored_run import Point

Floats = npt.NDArray[np.float64]

BUDGET_PARTS = ("statistical", "systematic", "combined", "expanded")
COVERAGE_K = 2.0  # k of U for a known covariance (reduction.statistics.coverage_factor)


def _num(v: Any) -> float:
    return math.nan if v is None else float(v)


def coverage_of(result: dict[str, Any]) -> float:
    """k of an `identify --json` object's statistical U (reduction.statistics.coverage_factor of
    its ``interval`` and ``dof``; 2 for a result stored before ``interval`` was)."""
    interval = result.get("interval")
    return coverage_factor(interval, int(result.get("dof") or 0)) if interval else COVERAGE_K


def expanded_uncertainty(result: dict[str, Any]) -> dict[str, float]:
    """U of each coefficient of an `identify --json` object as stored (SI): the sweep's
    ``expanded_uncertainty`` (orbitrig.run.point_analysis, calibration included when
    stated), else the stored budget's expanded uncertainty, else k x the standard error
    (statistical only; k of :func:`coverage_of`). NaN where none is known."""
    names = list(result.get("coefficients") or {})
    budget = (result.get("expanded_uncertainty") or {}).get("values") or (result.get("uncertainty") or {}).get(
        "expanded"
    )
    if budget:
        return {k: _num(budget.get(k)) for k in names}
    std, k_cov = result.get("std_errors") or {}, coverage_of(result)
    return {k: k_cov * _num(std.get(k)) for k in names}


def expanded_k(result: dict[str, Any]) -> float:
    """k of the U that :func:`expanded_uncertainty` gives ``result`` (the same order of sources)."""
    stored = result.get("expanded_uncertainty") or {}
    if stored.get("values"):
        return _num(stored.get("k", COVERAGE_K))
    unc = result.get("uncertainty") or {}
    if unc.get("expanded"):
        return _num(unc.get("k", COVERAGE_K))
    return coverage_of(result)


def expanded_ks(result: dict[str, Any]) -> dict[str, float]:
    """k of each coefficient's U that :func:`expanded_uncertainty` gives ``result``: the stored
    ``k_values`` (the sweep's combined U: Student's t at each coefficient's effective dof,
    reduction.combined_dof), else :func:`expanded_k` for every coefficient (a run stored before
    them, or statistical only). The one owner of the k a table, figure or export states per row."""
    names = list(result.get("coefficients") or {})
    for part in (result.get("expanded_uncertainty") or {}, result.get("uncertainty") or {}):
        if part.get("values") or part.get("expanded"):
            ks = part.get("k_values") or {}
            if ks:
                return {k: _num(ks.get(k)) for k in names}
            break
    return dict.fromkeys(names, expanded_k(result))


def uncertainty_basis(result: dict[str, Any]) -> UncertaintyBasis:
    """What :func:`expanded_uncertainty` of ``result`` rests on: COMBINED (calibration included)
    or STATISTICAL (k x the standard error, k of :func:`expanded_k`: no calibration stated)."""
    stored = result.get("expanded_uncertainty") or {}
    if stored.get("values"):
        return UncertaintyBasis(stored.get("basis", UncertaintyBasis.COMBINED))
    if (result.get("uncertainty") or {}).get("expanded"):
        return UncertaintyBasis.COMBINED
    return UncertaintyBasis.STATISTICAL


#: ``interval_95_basis``, the text of what interval_95 = value -+ U rests on, per UncertaintyBasis
INTERVAL_BASIS = {UncertaintyBasis.COMBINED: "combined", UncertaintyBasis.STATISTICAL: "statistical only"}


def coverage_interval(result: dict[str, Any]) -> tuple[dict[str, tuple[float, float]], str]:
    """``interval_95`` of an `identify --json` object as stored: value -+ U of each coefficient
    (SI; U of :func:`expanded_uncertainty`, k of :func:`expanded_k`: about 95 % coverage, 95.45 %
    at k = 2) and its basis text (INTERVAL_BASIS: combined | statistical only). NaN where the
    value or U is unknown. The fit's own ``confidence_95`` is the statistical-only interval."""
    U = expanded_uncertainty(result)
    values = result.get("coefficients") or {}
    out = {k: (_num(values.get(k)) - U[k], _num(values.get(k)) + U[k]) for k in U}
    return out, INTERVAL_BASIS[uncertainty_basis(result)]


@dataclass(frozen=True)
class FitRecord:
    """One identification of one point and load measuring system (SI)."""

    point: int
    lms: LoadSystem | None  # None: a table in memory (orbitrig.identify_table)
    model: str
    freq_dep: str
    method: str
    error: str = ""  # why the model was refused ("" for a fit)
    names: list[str] = field(default_factory=list)
    units: list[str] = field(default_factory=list)
    value: Floats = field(default_factory=lambda: np.zeros(0))
    std: Floats = field(default_factory=lambda: np.zeros(0))
    U: Floats = field(default_factory=lambda: np.zeros(0))  # expanded uncertainty, see expanded_uncertainty
    covariance: Floats | None = None  # (q, q) over covariance_names
    covariance_names: list[str] = field(default_factory=list)
    budget: dict[str, Floats] = field(default_factory=dict)  # BUDGET_PARTS aligned with names; "k"
    adequacy: dict[str, Any] | None = None
    derived: dict[str, Any] | None = None
    lms_consistency: dict[str, Any] | None = None
    result: dict[str, Any] | None = None  # the whole `identify --json` object as stored

    @property
    def key(self) -> str:
        """``<lms>__<model>__<freq_dep>__<method>`` as in run.h5 (':' and ',' -> '_')."""
        return f"{self.lms or ''}__{self.model}__{self.freq_dep.replace(':', '_').replace(',', '_')}__{self.method}"


def fit_record(
    point: int,
    lms: LoadSystem | None,
    model: str,
    freq_dep: str,
    method: str,
    result: dict[str, Any] | None,
    error: str | None = None,
) -> FitRecord:
    """The FitRecord of a stored identification (``result`` None: a refused model)."""
    if result is None:
        return FitRecord(point, lms, model, freq_dep, method, error or "")
    names = list(result.get("coefficients") or {})

    def vector(d: dict[str, Any] | None) -> Floats:
        return np.array([_num((d or {}).get(k)) for k in names], dtype=float)

    U = expanded_uncertainty(result)
    cov = result.get("covariance")
    unc = result.get("uncertainty") or {}
    budget = {part: vector(unc.get(part)) for part in BUDGET_PARTS if unc.get(part)}
    if budget:
        budget["k"] = np.array(float(unc.get("k", COVERAGE_K)))
    return FitRecord(
        point,
        lms,
        model,
        freq_dep,
        method,
        error or "",
        names,
        [coefficient_unit(k) for k in names],
        vector(result.get("coefficients")),
        vector(result.get("std_errors")),
        np.array([U[k] for k in names]),
        None if cov is None else np.array([[_num(v) for v in row] for row in cov], dtype=float),
        list(result.get("free") or names) if cov is not None else [],
        budget,
        result.get("adequacy"),
        result.get("derived"),
        result.get("lms_consistency"),
        result,
    )


def point_fits(point: Point) -> list[FitRecord]:
    """Every stored identification of an orbitrig.store.stored_run.Point, in stored order."""
    return [
        fit_record(point.index, i.lms, i.model, i.freq_dep, i.method, i.result, i.error) for i in point.identifications
    ]
