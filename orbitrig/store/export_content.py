"""What every export carries, as plain arrays with units (orbitrig.store.export).

The same content goes into each format: provenance (with the calibration record's and
the simulator scenario's TOML text), the point's settings, its orbit tables (with the whirl
direction), every fit's coefficients with std, U and ``interval_95`` = value -+ U (its
``interval_95_basis``: combined, or statistical only without a stated calibration uncertainty)
beside the fit's statistical-only 95 % interval ``interval_95_statistical``, covariance with
the names of its rows, budget, goodness of fit (dof, chi2, p_value, aic, bic), interval (where
the statistical interval's quantile comes from) and the coverage factor k of U, notes and warnings, derived quantities
(with the C_eff zero crossings and the covariance they rest on) and adequacy (with its test), the simulator's truth, the averaged waveforms, and each
block's spin turns per board revolution its runout is placed with (RUNOUT_TURNS). Units are
SI strings pint parses.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from daq.frames import slot_angle
from orbitrig.store.fit_analysis import c_eff_zero
from orbitrig.store.fit_record import (
    BUDGET_PARTS,
    INTERVAL_BASIS,
    FitRecord,
    coverage_interval,
    expanded_k,
    expanded_ks,
    uncertainty_basis,
)
from orbitrig.store.layout import DERIVED_UNITS, INTERVAL_BASIS_MEANING, POINT_STATE, SETTINGS_UNITS
from orbitrig.store.orbit_table import orbit_table_columns
from orbitrig.store.truth_data import truth_data
from reduction.runout_slip import RESOLVED
from rigunits import ONE, TEXT

if TYPE_CHECKING:
    from orbitrig.store.stored_run import Point, Run
    from reduction.table import OrbitTable

#: a column: values and their unit
Column = tuple[npt.NDArray[Any], str]

#: derived quantities: name -> unit (each also with _std)
#: the adequacy test's numbers (unit 1; supported: 1 yes, 0 no) and its text
ADEQUACY_NUMBERS = ("supported", "p_value", "statistic", "dof", "alpha", "aic", "bic")
ADEQUACY_TEXT = ("verdict", "test", "constant")
#: a fit's single values beside the adequacy test (docs/orbit-table.md): name -> (unit, meaning), unit "" for text
FIT_QUALITY = {
    "dof": ("1", "degrees of freedom: 4 x rows - free coefficients"),
    "chi2": ("1", "chi-square of the residual against the stated u_* (only with u_*)"),
    "p_value": ("1", "upper-tail probability of chi2 with dof degrees of freedom"),
    "aic": ("1", "Akaike information criterion of the fit"),
    "bic": ("1", "Bayesian information criterion of the fit"),
    "interval": ("", "quantile of interval_95_statistical: normal (covariance from the stated u_*) or student_t (dof)"),
    "confidence_level": ("1", "two-sided level of interval_95_statistical (statistical only)"),
    "k": ("1", "the largest coverage factor of the fits' U (each coefficient's: expanded_k); interval_95 = value -+ U"),
    "interval_95_basis": ("", INTERVAL_BASIS_MEANING),
}
CONFIDENCE_LEVEL = 0.95  # of the identification's confidence_95 (interval_95_statistical)
#: the names of an array's entries where a format flattens it (``<name>_<part>``)
ARRAY_PARTS: dict[str, tuple[str, ...]] = {
    "adequacy_dof": ("numerator", "denominator"),
    "adequacy_aic": ("constant", "fit"),
    "adequacy_bic": ("constant", "fit"),
    "c_eff_zero_xx": ("omega_0", "std"),
    "c_eff_zero_yy": ("omega_0", "std"),
}
#: run.h5's runout_turns (docs/storage.md) as the exports carry it, one entry per block in the orbit
#: table's row order: name -> (unit, meaning), unit "" for text
RUNOUT_TURNS = {
    "orbit_hz": ("Hz", "the block's planned orbit frequency (the orbit table's row)"),
    "direction": (ONE, "the block's whirl: +1 forward, -1 backward"),
    "commanded": (
        ONE,
        "spin turns per board revolution commanded: spin over the orbit speed as written to the drives"
        " (their REF counts; the planned speeds in a run written before those were stored)",
    ),
    "fitted": (ONE, "spin turns per board revolution fitted from the block's probe samples (NaN: not fitted)"),
    "u": (ONE, "standard uncertainty of fitted (NaN: not fitted)"),
    "resolved": (ONE, f"1: fitted is off commanded by more than {RESOLVED:g} u and is used; 0: commanded is used"),
    "used": (ONE, "spin turns per board revolution the runout is placed with and the spin tones fitted at"),
    "unfitted": (TEXT, "why the ratio was not fitted (empty when it was)"),
}
#: the point's numeric settings every export carries: name -> unit
SETTINGS = {k: u for k, u in SETTINGS_UNITS.items() if u != TEXT and k not in POINT_STATE}


def provenance(run: Run) -> dict[str, str]:
    """Text describing where the data came from: the software, the run's status and
    configuration, the simulator scenario (name and TOML text), and who ran it where with
    which calibration record (its SHA-256 and TOML text), when."""
    return {
        "software_version": run.software_version,
        "software_versions": "; ".join(run.software_versions),  # that measured the points: two or more after a resume
        "created": run.created,
        "status": str(run.status),
        "status_message": run.status_message,
        "sim": str(bool(run.sim)).lower(),
        "matrix_name": run.matrix_name,
        "rig_config": run.rig_config,
        "matrix_config": run.matrix_config,
        "sim_scenario_name": run.sim_scenario_name,
        "sim_scenario_config": run.sim_scenario_config,
        **run.provenance,
        "calibration_record_text": run.calibration_record_text,
    }


def settings(point: Point) -> dict[str, tuple[float, str]]:
    """The point's numeric settings: name -> (value, unit)."""
    st = point.settings
    return {k: (float(getattr(st, k)), u) for k, u in SETTINGS.items()}


def table_columns(table: OrbitTable) -> dict[str, Column]:
    """The orbit-table columns with ``direction`` (+1 forward, -1 backward), as the CSV has them."""
    return orbit_table_columns(table, direction=True)


def fit_arrays(fit: FitRecord) -> dict[str, Any]:
    """One fit as arrays: names, units, value, std, U, ``interval_95`` (p, 2: low, high; value
    -+ U, basis in ``interval_95_basis``), ``interval_95_statistical`` (p, 2: the fit's own
    confidence_95, statistical only), covariance (+ covariance_names), the budget's parts, the FIT_QUALITY values (dof, chi2,
    p_value, aic, bic where the fit gives them; interval, confidence_level; k, the largest of U's),
    ``expanded_k`` (each coefficient's k of U, orbitrig.store.fit_record.expanded_ks), the
    adequacy numbers and verdict, E_n, ``not_determined`` (1 where U exceeds the magnitude),
    the fit's own ``truth`` (--sim) aligned with names, and its ``notes`` and ``warnings``."""
    result = fit.result or {}
    d: dict[str, Any] = {
        "names": fit.names,
        "units": fit.units,
        "value": fit.value,
        "std": fit.std,
        "U": fit.U,
        "error": fit.error,
    }
    if fit.result is not None:
        lo_hi, _ = coverage_interval(fit.result)
        d["interval_95"] = np.array([lo_hi[k] for k in fit.names], dtype=float).reshape(-1, 2)
    if "confidence_95" in result:
        ci = result["confidence_95"] or {}
        stat = np.array([_number(ci.get(k) or [None, None]) for k in fit.names]).reshape(-1, 2)
        d["interval_95_statistical"] = stat
    if fit.covariance is not None:
        d["covariance"], d["covariance_names"] = fit.covariance, fit.covariance_names
    d.update({part: fit.budget[part] for part in BUDGET_PARTS if part in fit.budget})
    if fit.result is not None:
        d.update(fit_quality(fit))
        ks = expanded_ks(fit.result)  # each U's own k, beside U (fit_quality's k: the largest)
        d["expanded_k"] = np.array([ks.get(k, math.nan) for k in fit.names], dtype=float)
    if fit.adequacy:
        d.update({f"adequacy_{k}": str(fit.adequacy.get(k, "")) for k in ADEQUACY_TEXT})
        d.update({f"adequacy_{k}": _number(fit.adequacy.get(k)) for k in ADEQUACY_NUMBERS})
    if fit.lms_consistency and "e_n" in fit.lms_consistency:
        d["e_n"] = np.array([_number(fit.lms_consistency["e_n"].get(k)) for k in fit.names])
    if "not_determined" in result:
        d["not_determined"] = np.array([k in result["not_determined"] for k in fit.names], dtype=np.uint8)
    own = (result.get("truth") or {}).get("coefficients")
    if own is not None:  # the simulator's truth projected onto this fit's model
        d["truth"] = np.array([_number(own.get(k)) for k in fit.names])
    d["notes"], d["warnings"] = list(result.get("notes") or []), list(result.get("warnings") or [])
    return d


def fit_quality(fit: FitRecord) -> dict[str, float | str]:
    """The FIT_QUALITY values of a fit: dof, chi2, p_value, aic, bic as its result gives them
    (null: NaN), its ``interval`` and the ``confidence_level`` of its interval_95_statistical,
    ``k``, the largest coverage factor of its U (orbitrig.store.fit_record.expanded_k; each
    coefficient's is fit_arrays' ``expanded_k``), and
    ``interval_95_basis`` (INTERVAL_BASIS of orbitrig.store.fit_record.uncertainty_basis)."""
    result = fit.result or {}
    d: dict[str, float | str] = {k: _scalar(result[k]) for k in ("dof", "chi2", "p_value", "aic", "bic") if k in result}
    if "interval" in result:
        d["interval"] = str(result["interval"] or "")
    if "confidence_95" in result:
        d["confidence_level"] = CONFIDENCE_LEVEL
    d["k"] = expanded_k(result)
    d["interval_95_basis"] = INTERVAL_BASIS[uncertainty_basis(result)]
    return d


def derived_columns(fit: FitRecord) -> dict[str, Column]:
    """The derived quantities at the point's orbit frequencies: name -> (values, unit)."""
    d = fit.derived or {}
    if "orbit_hz" not in d:
        return {}
    cols: dict[str, Column] = {"orbit_hz": (np.asarray(d["orbit_hz"], dtype=float), "Hz")}
    for name, unit in DERIVED_UNITS.items():
        for key in (name, f"{name}_std"):
            if key in d:
                cols[key] = (np.array([_number(v) for v in d[key]]), unit)
    for name in ("h_forward", "h_backward"):
        if f"{name}_re" in d:
            std = np.asarray(d.get(f"{name}_std"), dtype=float)
            cols.update(
                {
                    f"{name}_re": (np.asarray(d[f"{name}_re"], dtype=float), "N/m"),
                    f"{name}_im": (np.asarray(d[f"{name}_im"], dtype=float), "N/m"),
                    f"{name}_std_re": (std[0], "N/m"),
                    f"{name}_std_im": (std[1], "N/m"),
                }
            )
    return cols


def derived_properties(fit: FitRecord) -> dict[str, tuple[Any, str]]:
    """What the derived quantities rest on: name -> (value, unit). ``covariance`` (text:
    combined | statistical, the covariance behind every _std) and, where C_eff changes
    sign, ``c_eff_zero_xx`` / ``c_eff_zero_yy``: (Omega_0, its std) in rad/s."""
    d = fit.derived or {}
    if "orbit_hz" not in d:
        return {}
    out: dict[str, tuple[Any, str]] = {"covariance": (str(d.get("covariance", "")), "")}
    for k in ("xx", "yy"):
        zero = c_eff_zero(d, k)
        if zero is not None:
            out[f"c_eff_zero_{k}"] = (zero, "rad/s")
    return out


def fit_properties(fit: FitRecord) -> dict[str, tuple[float | str, str]]:
    """The fit's single values: FIT_QUALITY (dof, chi2, p_value, aic, bic, interval,
    confidence_level, k of U) and the adequacy test (numbers unit 1, verdict, test and
    constant text, unit ""), an array one entry per name (ARRAY_PARTS)."""
    d = fit_arrays(fit)
    return flat(
        {
            k: (v, "" if isinstance(v, str) else "1")
            for k, v in d.items()
            if k in FIT_QUALITY or k.startswith("adequacy_")
        }
    )


def flat(props: dict[str, tuple[Any, str]]) -> dict[str, tuple[float | str, str]]:
    """`props` with each array as one entry per part: ``adequacy_dof`` -> ``adequacy_dof_numerator``,
    ``adequacy_dof_denominator`` (ARRAY_PARTS; else ``_0``, ``_1``, ...); numbers as floats."""
    out: dict[str, tuple[float | str, str]] = {}
    for name, (value, unit) in props.items():
        if isinstance(value, str):
            out[name] = (value, unit)
            continue
        values = np.ravel(value)
        if values.size == 1:
            out[name] = (float(values[0]), unit)
            continue
        parts: tuple[str, ...] = ARRAY_PARTS.get(name, ())
        if len(parts) != values.size:
            parts = tuple(str(i) for i in range(values.size))
        out |= {f"{name}_{part}": (float(x), unit) for part, x in zip(parts, values)}
    return out


def truth_arrays(truth: dict[str, Any] | None) -> dict[str, Column]:
    """The simulator's truth (orbitrig.store.truth_data, as RunData.truth gives it): K0, C0, D0
    (2 x 2, the constant best fit), Z (complex, row x 2 x 2) at ``orbit`` (signed) and
    ``orbit_hz``, the ``band`` of |Omega| the best fits use, and the Eq. 15 best fit as
    ``power_K0``, ``power_Km`` ... ``power_Dp`` (2 x 2) and ``power_exponents`` (m, n, p)."""
    t = truth_data(truth) if truth else None
    if not t:
        return {}
    units = t["units"]
    out: dict[str, Column] = {k: (t[k], units[k]) for k in ("K0", "C0", "D0") if k in t}
    if "Z_re" in t:
        out["Z"] = (t["Z_re"] + 1j * t["Z_im"], units["Z_re"])
    out |= {k: (t[k], units[k]) for k in ("orbit", "orbit_hz", "band") if k in t}
    power = (t.get("fits") or {}).get("power") or {}
    out |= {f"power_{k}": (power[k], u) for k, u in power.get("units", {}).items()}
    if "exponents" in power:
        out["power_exponents"] = (np.asarray(power["exponents"], dtype=float), "1")
    return out


def runout_turns_columns(turns: dict[str, Any] | None) -> dict[str, Column]:
    """A point's ``runout_turns`` (Point.runout_turns, run.h5's json) as RUNOUT_TURNS columns
    (values, unit), one row per block in the orbit table's row order: numbers float64 (None: NaN),
    ``resolved`` uint8 (1 true), ``unfitted`` text; {} for a point without them (a run of an
    earlier version)."""
    if not turns:
        return {}
    out: dict[str, Column] = {}
    for name, (unit, _) in RUNOUT_TURNS.items():
        values = turns.get(name, [])
        if name == "unfitted":
            out[name] = (np.array([str(v or "") for v in values], dtype=str), unit)
        elif name == "resolved":
            out[name] = (np.array([1 if v else 0 for v in values], dtype=np.uint8), unit)
        else:
            out[name] = (np.array([math.nan if v is None else float(v) for v in values], dtype=float), unit)
    return out


def waveform_arrays(point: Point, channels: list[str]) -> list[dict[str, Any]]:
    """Each block's averaged revolution: name, orbit_hz, direction, n_records, and per
    channel mean (S,), theta (S,, rad), dc, phasor (complex), uncertainty."""
    blocks = []
    for f in point.frequencies:
        w = f.waveform
        if "mean" not in w:
            continue
        b: dict[str, Any] = {
            "name": f.name,
            "orbit_hz": f.orbit_hz,
            "direction": f.direction,
            "n_records": f.n_records,
            "mean": w["mean"],
            "theta": slot_angle(w["slots"]),
        }
        b.update({k: w[k] for k in ("dc", "phasors", "uncertainty") if k in w})
        b["channels"] = channels
        blocks.append(b)
    return blocks


def _scalar(v: Any) -> float:
    """A stored single number (None: NaN)."""
    return math.nan if v is None else float(v)


def _number(v: Any) -> float | npt.NDArray[np.float64]:
    """A stored number (None: NaN; a list, e.g. an F test's two dof: an array)."""
    if isinstance(v, (list, tuple)):
        return np.array([math.nan if x is None else float(x) for x in v])
    return math.nan if v is None else float(v)
