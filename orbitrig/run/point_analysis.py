"""A point's identifications judged: uncertainty budget, model adequacy, the two load
measuring systems' consistency, and derived quantities (pure, no I/O; worker thread).

Each result is added to the identification's stored JSON object (the orbit-table v2
object of `identify --json`) under its own key:

- ``uncertainty``: {"statistical", "systematic", "combined", "expanded", "sources",
  "source_std"} per coefficient (SI), from reduction.systematic.uncertainty_budget with the
  rig's stated calibration uncertainty (absent when the rig states none); "expanded", "k_values"
  and "dof" per coefficient: U, its coverage factor and the effective dof of the combined u (None: infinite;
  reduction.combined_dof, the calibration's dof from the active record's fits,
  orbitrig.run.calibration_dof, "dof_notes" where it states none), "k" the largest; "source_dof"
  each source's dof (aligned with "sources"; None: exact), so a fit made later from the table
  rebuilds its k (quality.budget_coverage); with the subtracted
  runout's recorded uncertainty also "runout" (its standard uncertainty per coefficient, inside
  "systematic"), "runout_covariance" (p x p, SI, free-coefficient order) and "runout_dof";
- ``adequacy`` (frequency-dependent fits only): reduction.adequacy.frequency_dependence
  against the constant fit of the same model and method, plus "constant" (its spec);
- ``lms_consistency``: {"e_n": {key: E_n}, "max_abs", "consistent", "test": "chi2", "chi2",
  "dof", "level", "limit", "p_value", "basis", "pair"}: the normalised difference piezo - strain
  of the same model per coefficient, and ``consistent`` judged for all coefficients at once
  (chi2 <= limit, the chi2(dof) quantile at the family-wise false-flag level, 5 %;
  reduction.lms_comparison.lms_agreement);
- ``expanded_uncertainty``: {"k", "k_values", "basis": "combined" | "statistical", "values": {key: U}}
  (k_values per coefficient, k the largest: the budget's; statistical: coverage_factor, 2 with the stated u_*),
  the expanded uncertainty of every coefficient: its k times the combined standard uncertainty
  (statistical and calibration), or k times the statistical one when the rig states no
  calibration uncertainty or the budget failed; ``not_determined``: the coefficients whose U
  exceeds their magnitude (reduction.statistics.not_determined; orbit-table v3);
- ``derived``: reduction.derived.derived_quantities at the point's planned orbit frequencies,
  with the combined covariance when there is one (``derived["covariance"]`` says which).

A step that cannot be evaluated stores {"error": reason} under its key instead. Both ``basis``
values are the text of a reduction.systematic.UncertaintyBasis (plain JSON, as read back).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, cast

import numpy as np

from orbitrig.config import LMS, CalibrationUncertainty, ChannelName, ModelSpec
from orbitrig.load_systems import LoadSystem
from orbitrig.run.calibration_dof import CalibrationDof
from orbitrig.store.records import IdentificationEntry
from reduction.arrays import FloatArray
from orbitrig.store.fit_record import coverage_of
from reduction.adequacy import frequency_dependence
from reduction.derived import derived_quantities
from reduction.errors import ReductionError
from reduction.identify import identify
from reduction.models import CONSTANT
from reduction.result import Identification
from reduction.statistics import not_determined
from reduction.combined_dof import combined_coverage, source_dof
from reduction.lms_comparison import lms_agreement
from reduction.systematic import (
    Budget,
    Calibration,
    ChannelCalibration,
    DisplacementTerm,
    UncertaintyBasis,
    uncertainty_budget,
)
from reduction.table import OrbitTable

_FAILURES = (ReductionError, np.linalg.LinAlgError, ValueError, ZeroDivisionError)


def lms_calibration(stated: CalibrationUncertainty, lms: LoadSystem, dof: CalibrationDof | None = None) -> Calibration:
    """The calibration uncertainty of one load measuring system's orbit table (SI): x, y are
    the probe-plane means, their uncertainty the mean of the two probes' (taken as fully
    correlated, the conservative choice; their dof the smaller); fx, fy the system's force
    channels; each with its dof from ``dof`` (None: every part exact)."""
    dof = dof or CalibrationDof()

    def chan(name: ChannelName) -> ChannelCalibration:
        c = stated.channel(name)
        return ChannelCalibration(c.gain, c.phase, c.delay, dof.gain_of(name), dof.lag_of(name))

    def mean(a: ChannelName, b: ChannelName) -> ChannelCalibration:
        ca, cb = chan(a), chan(b)
        return ChannelCalibration(
            (ca.gain + cb.gain) / 2,
            (ca.phase + cb.phase) / 2,
            (ca.delay + cb.delay) / 2,
            min(ca.gain_dof, cb.gain_dof),
            min(ca.lag_dof, cb.lag_dof),
        )

    return Calibration(
        x=mean("x_a", "x_b"),
        y=mean("y_a", "y_b"),
        fx=chan(cast(ChannelName, f"fx_{lms}")),  # the system's force channels, named from it
        fy=chan(cast(ChannelName, f"fy_{lms}")),
        sensitivity=stated.probe_sensitivity,
    )


def analyse_point(
    spin: float,
    tables: dict[LoadSystem, OrbitTable],
    fits: dict[tuple[LoadSystem, str], Identification],
    idents: dict[tuple[LoadSystem, str], IdentificationEntry],
    stated: CalibrationUncertainty | None,
    grid: FloatArray,
    runout: DisplacementTerm | None = None,
    dof: CalibrationDof | None = None,
) -> None:
    """Add budget, adequacy, LMS consistency and derived quantities to the stored JSON of every
    fit in ``idents`` ((lms, ModelSpec.key) -> {"spec", "json"}); ``fits`` the same fits'
    Identification objects; ``grid`` the point's orbit frequencies for the derived quantities
    (rad/s, > 0: the planned ones, forward and backward blocks of one frequency are one);
    ``runout`` the subtracted runout's uncertainty as common displacement errors of the point's
    rows (orbitrig.run.identification.runout_term; both systems' tables share x, y), in the budget
    with the stated calibration; ``dof`` the stated calibration's degrees of freedom (the active
    record's fits, orbitrig.run.calibration_dof; None: every part exact)."""
    dof = dof or CalibrationDof()
    cal: dict[LoadSystem, Calibration] | None = (
        {lms: lms_calibration(stated, lms, dof) for lms in LMS} if stated is not None else None
    )
    budgets: dict[tuple[LoadSystem, str], Budget] = {}
    for (lms, key), ident in fits.items():
        d = idents[(lms, key)]["json"]
        if cal is not None:
            d["uncertainty"] = _guarded(_budget, ident, tables[lms], cal[lms], budgets, (lms, key), runout, dof.notes)
        d["expanded_uncertainty"] = expanded_uncertainty(d)
        values = {k: v for k, v in d["coefficients"].items() if v is not None}
        d["not_determined"] = not_determined(values, d["expanded_uncertainty"]["values"])
        d["derived"] = _guarded(_derived, ident, grid, spin, budgets.get((lms, key)))
        if not ident.constant:
            d["adequacy"] = _guarded(_adequacy, ident, tables[lms], fits, lms, idents[(lms, key)]["spec"])
    for key in {k for _, k in fits}:
        a, b = fits.get((LMS[0], key)), fits.get((LMS[1], key))
        if a is None or b is None:
            continue
        out = _guarded(_consistency, a, tables[LMS[0]], b, tables[LMS[1]], cal, runout)
        for lms in LMS:
            idents[(lms, key)]["json"]["lms_consistency"] = out


def expanded_uncertainty(d: dict[str, Any]) -> dict[str, Any]:
    """{"k", "k_values", "basis", "values"} of a fit's stored JSON ``d``: its budget's expanded
    (combined) uncertainty where there is one (each coefficient's k in "k_values", the largest in
    "k"), else k times the statistical standard error (k of the fit's interval and dof,
    orbitrig.store.fit_record.coverage_of: 2 with the stated u_*)."""
    u = d.get("uncertainty") or {}
    if u.get("expanded"):
        return {
            "k": float(u["k"]),
            "k_values": dict(u.get("k_values") or dict.fromkeys(u["expanded"], float(u["k"]))),
            "basis": UncertaintyBasis.COMBINED.value,
            "values": dict(u["expanded"]),
        }
    std, k_cov = d.get("std_errors") or {}, coverage_of(d)
    values = {k: (None if std.get(k) is None else k_cov * std[k]) for k in d["coefficients"]}
    ks = dict.fromkeys(d["coefficients"], k_cov)
    return {"k": k_cov, "k_values": ks, "basis": UncertaintyBasis.STATISTICAL.value, "values": values}


def _guarded(fn: Callable[..., dict[str, Any]], *args: object) -> dict[str, Any]:
    try:
        return fn(*args)
    except _FAILURES as err:
        return {"error": str(err)}


def _budget(
    ident: Identification,
    table: OrbitTable,
    cal: Calibration,
    budgets: dict[tuple[LoadSystem, str], Budget],
    where: tuple[LoadSystem, str],
    runout: DisplacementTerm | None = None,
    dof_notes: list[str] | None = None,
) -> dict[str, Any]:
    b = uncertainty_budget(ident, table, cal, runout=runout)
    budgets[where] = b
    cov = combined_coverage(ident, b, cal, math.inf if runout is None else runout.dof)
    dofs = source_dof(cal)
    _, sigma = cal.parameters()
    extra: dict[str, Any] = {}
    if b.covariance_runout is not None:
        extra = {"runout": b.runout, "runout_covariance": b.covariance_runout.tolist()}
        extra["runout_dof"] = runout.dof if runout is not None and math.isfinite(runout.dof) else None
    return extra | {
        "k": max(cov.k.values()),
        "k_values": cov.k,
        "dof": {key: _finite(v) for key, v in cov.dof.items()},
        "dof_notes": list(dof_notes or []),
        "statistical": b.statistical,
        "systematic": b.systematic,
        "combined": b.combined,
        "expanded": cov.expanded,
        "sources": list(b.labels),
        "source_std": [float(s) for s in sigma],
        "source_dof": [_finite(dofs[n]) for n in b.labels],  # each source's dof (None: exact): rebuilds k
    }


def _finite(v: float) -> float | None:
    """A dof as stored: None for infinitely many (strict JSON)."""
    return v if math.isfinite(v) else None


def _derived(ident: Identification, grid: FloatArray, spin: float, budget: Budget | None) -> dict[str, Any]:
    cov = budget.covariance_combined if budget is not None else None
    combined = cov is not None
    d = derived_quantities(ident, grid, spin, cov=cov).to_dict()
    d["covariance"] = "combined" if combined else ("statistical" if ident.covariance is not None else "none")
    return d


def _adequacy(
    ident: Identification,
    table: OrbitTable,
    fits: dict[tuple[LoadSystem, str], Identification],
    lms: LoadSystem,
    spec: ModelSpec,
) -> dict[str, Any]:
    constant = next(
        (
            f
            for (ls, _), f in fits.items()
            if ls == lms and f.model == ident.model and f.constant and f.method == ident.method
        ),
        None,
    )
    if constant is None:  # not configured: fitted here for the test only
        constant = identify(table, model=spec.model, freq_dep=CONSTANT.text, method=spec.method)
    out = frequency_dependence(constant, ident).to_dict()
    out["constant"] = f"{constant.model} {CONSTANT.text} {constant.method}"
    return out


def _consistency(
    a: Identification,
    ta: OrbitTable,
    b: Identification,
    tb: OrbitTable,
    cal: dict[LoadSystem, Calibration] | None,
    runout: DisplacementTerm | None = None,
) -> dict[str, Any]:
    none = Calibration()
    ca, cb = (cal[LMS[0]], cal[LMS[1]]) if cal is not None else (none, none)
    ag = lms_agreement(a, ta, b, tb, ca, cb, runout=runout if cal is not None else None)
    return {
        "e_n": ag.e_n,
        "max_abs": ag.max_abs,
        "consistent": ag.consistent,
        "test": "chi2",
        "chi2": ag.chi2,
        "dof": ag.dof,
        "level": ag.level,
        "limit": ag.limit,
        "p_value": ag.p_value,
        "basis": (UncertaintyBasis.COMBINED if cal is not None else UncertaintyBasis.STATISTICAL).value,
        "pair": f"{LMS[0]} - {LMS[1]}",
    }
