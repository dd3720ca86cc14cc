"""A stored run as catalog rows: one per complete operating point and stored fit.

Each row holds the point's conditions (SI), the fit's key (load measuring system, model,
frequency dependence, method), the twelve constant coefficients K, C, D (N/m, N s/m, kg)
and their expanded uncertainties U (k = 2), every coefficient of the fit as JSON, the
adequacy verdict, the run's provenance (the bearing tested among it) and its directory (docs/catalog.md).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from orbitrig.catalog.bearing import bearing_columns
from orbitrig.store.fit_record import COVERAGE_K, expanded_k, expanded_ks, expanded_uncertainty, uncertainty_basis
from orbitrig.store.stored_run import Point, Run, StoredIdentification
from rigunits import COEFFICIENT_UNITS, coefficient_unit, without_noise

#: the constant coefficients every model reports (absent ones are NULL)
COEFFICIENTS = tuple(f"{m}{ij}" for m in "KCD" for ij in ("xx", "xy", "yx", "yy"))
#: SI unit of each coefficient family
UNITS = COEFFICIENT_UNITS
#: k of U for a row catalogued before coefficients_json stored the fit's own k
COVERAGE = COVERAGE_K


def _number(value: Any) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def run_rows(run: Run, points: list[Point] | None = None) -> list[dict[str, Any]]:
    """The catalog rows of ``points`` (default: the run's complete points)."""
    points = run.complete_points if points is None else points
    common = _run_columns(run)
    return [{**common, **_point_columns(p), **_fit_columns(i)} for p in points for i in p.identifications]


def _run_columns(run: Run) -> dict[str, Any]:
    prov = run.provenance
    return {
        "run_id": run.run_id,
        "run_path": str(Path(run.directory).resolve()),
        "run_status": str(run.status),
        "created": run.created,
        "matrix_name": run.matrix_name,
        "sim": run.sim,
        "software_version": run.software_version,
        "operator": prov.get("operator", ""),
        "rig_id": prov.get("rig_id", ""),
        "host": prov.get("host", ""),
        "calibration_record": prov.get("calibration_record", ""),
        "calibration_record_sha256": prov.get("calibration_record_sha256", ""),
        "started": prov.get("started", ""),
        "ended": prov.get("ended", ""),
        **bearing_columns(run),
    }


def _point_columns(p: Point) -> dict[str, Any]:
    s = p.settings
    return {
        "point": p.index,
        "label": s.label,
        "spin": s.spin,
        "spin_rpm": s.spin_rpm,
        "recess_pressure": s.recess_pressure,
        "pressure_ratio": s.pressure_ratio,
        "static_eccentricity": s.static_eccentricity,
        "dynamic_eccentricity": s.dynamic_eccentricity,
        "orbit_hz": json.dumps(sorted({without_noise(f.orbit_hz) for f in p.frequencies})),  # as planned
    }


def _fit_columns(ident: StoredIdentification) -> dict[str, Any]:
    from reduction.statistics import not_determined

    row: dict[str, Any] = {
        "lms": ident.lms,
        "model": ident.model,
        "freq_dep": ident.freq_dep,
        "method": ident.method,
        "ok": ident.ok,
        "error": ident.error or "",
    }
    result = ident.result or {}
    values = {k: _number(v) for k, v in result.get("coefficients", {}).items()}
    u, basis = (expanded_uncertainty(result), uncertainty_basis(result)) if ident.ok else ({}, "")
    adequacy = result.get("adequacy") or {}
    row.update(
        n_frequencies=result.get("n_frequencies"),
        chi2=_finite(result.get("chi2")),
        p_value=_finite(result.get("p_value")),
        u_basis=basis,
        adequacy_verdict=str(adequacy.get("verdict", "")),
        adequacy_supported=adequacy.get("supported") if "supported" in adequacy else None,
        not_determined=" ".join(not_determined(values, u)),
        coefficients_json=json.dumps(
            {  # strict JSON: a number not known (a U or std that could not be estimated) is null
                "values": _finite_all(values),
                "U": _finite_all(u),
                "std": _finite_all(result.get("std_errors", {})),
                "k": _finite(expanded_k(result)) if ident.ok else None,  # U = k x the standard uncertainty
                "k_values": _finite_all(expanded_ks(result)) if ident.ok else {},  # each coefficient's k
                "units": {k: coefficient_unit(k) for k in values},  # SI, as pint parses them
            },
            allow_nan=False,
        ),
    )
    for name in COEFFICIENTS:
        row[name], row[f"{name}_U"] = _finite(values.get(name)), _finite(u.get(name))
    return row


def _finite_all(values: dict[str, Any]) -> dict[str, float | None]:
    """``values`` with each missing or non-finite number None (JSON null)."""
    return {k: _finite(v) for k, v in values.items()}


def _finite(value: Any) -> float | None:
    """A number for the database: None (NULL) for a missing or non-finite one."""
    x = _number(value)
    return x if math.isfinite(x) else None
