"""One operating point's bearing coefficients for ROSS at its spin omega (rad/s): from the chosen
stored fit (:class:`FitSpec`), at the synchronous whirl Omega = omega when the fit is frequency
dependent and omega lies in the point's tested whirl range, else the constant fit of the same
model and method (stored, else fitted here from the orbit table). Values in ROSS's keys (kxx ..
myy; N/m, N s/m, kg) with U: the fit's U for one order-0 coefficient, else the statistical
covariance propagated plus the calibration parts taken as fully correlated (an upper bound).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from orbitrig.analysis.quality import budget_coverage, budget_covariance, runout_left_out
from orbitrig.analysis.reduce import identify_point
from orbitrig.analysis.ross_warnings import ROSS_LETTERS, speed_warnings
from orbitrig.load_systems import LoadSystem
from orbitrig.store.csvfile import one_line
from orbitrig.store.fit_record import COVERAGE_K, coverage_of, expanded_ks, expanded_uncertainty, uncertainty_basis
from orbitrig.store.stored_run import Point
from reduction.methods import Method
from reduction.models import CONSTANT, is_constant
from reduction.statistics import not_determined
from reduction.result import Identification
from reduction.systematic import UncertaintyBasis
from reduction.table import OrbitTable

ENTRIES = ("xx", "xy", "yx", "yy")
KEYS = tuple(f"{c}{e}" for c in "kcm" for e in ENTRIES)  # ROSS's names
CONDITION = ("recess_pressure", "pressure_ratio", "static_eccentricity", "dynamic_eccentricity")  # a bearing's, SI


@dataclass(frozen=True)
class FitSpec:
    """A stored fit: load measuring system (None: every one), model, frequency dependence, method."""

    lms: LoadSystem | None
    model: str
    freq_dep: str = "none"
    method: Method = Method.OLS

    def text(self, lms: LoadSystem | None = None, freq_dep: str | None = None) -> str:
        """``LMS:MODEL:FREQ_DEP:METHOD`` (the form of ``--fit``)."""
        return f"{lms or self.lms or ''}:{self.model}:{freq_dep or self.freq_dep}:{self.method}"


def tested_frequencies(point: Point) -> np.ndarray:
    """The point's planned orbit frequencies |Omega| (rad/s), each once, ascending: one per
    tested orbit ratio (both whirl directions share it); the orbit tables' measured speeds
    only for a point stored without its blocks."""
    planned = [abs(f.orbit) for f in point.frequencies if f.complete]
    if planned:
        return np.unique(planned)
    measured = [np.abs(t.orbit) for t in point.tables.values()]
    return np.unique(np.concatenate(measured)) if measured else np.zeros(0)


def _ross_key(name: str) -> tuple[str, int]:
    """(ROSS key, order) of a coefficient name: ``Kxy_1`` -> ("kxy", 1)."""
    return ROSS_LETTERS[name[0]] + name[1:3], int(name.partition("_")[2] or 0)


def _num(v: Any) -> float:
    return math.nan if v is None else float(v)


def coefficients_at(result: dict[str, Any], omega: float) -> dict[str, float]:
    """K, C, D entries (ROSS keys) of a stored fit at whirl ``omega`` (rad/s): each entry's
    fitted orders summed, K(Omega) = sum_r Omega^r K_r; 0 for a matrix the model has not."""
    out = dict.fromkeys(KEYS, 0.0)
    for name, v in result["coefficients"].items():
        key, order = _ross_key(name)
        out[key] += _num(v) * omega**order
    return out


def uncertainties_at(result: dict[str, Any], omega: float) -> dict[str, float | None]:
    """U of each entry of :func:`coefficients_at` (None: not in the model). One coefficient of
    order 0: its stored U; a sum over orders: k sqrt(g' S g + (sum_r |g_r| u_sys,r)^2), S the
    statistical covariance, u_sys the calibration part of each order (fully correlated: an
    upper bound), k the largest of its orders' (orbitrig.store.fit_record.expanded_ks); NaN
    without a covariance."""
    U = expanded_uncertainty(result)
    terms: dict[str, list[tuple[str, int]]] = {}
    for name in result["coefficients"]:
        key, order = _ross_key(name)
        terms.setdefault(key, []).append((name, order))
    free, cov = list(result.get("free") or []), result.get("covariance")
    combined = uncertainty_basis(result) == UncertaintyBasis.COMBINED
    systematic = (result.get("uncertainty") or {}).get("systematic") or {} if combined else {}
    ks = expanded_ks(result)
    out: dict[str, float | None] = dict.fromkeys(KEYS)
    for key, names in terms.items():
        if len(names) == 1 and names[0][1] == 0:
            out[key] = U[names[0][0]]
            continue
        if cov is None:
            out[key] = math.nan
            continue
        g = np.zeros(len(free))
        for name, order in names:
            g[free.index(name if name in free else name[0] + name[2] + name[1] + name[3:])] += omega**order
        var = float(g @ np.array([[_num(v) for v in row] for row in cov]) @ g)
        sys = sum(abs(omega**order) * _num(systematic.get(name, 0.0)) for name, order in names)
        out[key] = max(ks[name] for name, _ in names) * math.sqrt(max(var, 0.0) + sys**2)
    return out


def _constant_fit(
    point: Point, lms: LoadSystem, spec: FitSpec, chosen: dict[str, Any]
) -> tuple[dict[str, Any], str] | str:
    """The constant fit of ``spec``'s model and method (stored, else fitted from the orbit
    table, its U on the calibration uncertainty of the ``chosen`` fit's budget when it has one)
    and its ``--fit`` text, or why there is none."""
    text = spec.text(lms, CONSTANT.text)
    stored = point.identification(lms, spec.model, CONSTANT.text, spec.method)
    if stored is not None and stored.result is not None:
        return stored.result, text
    if stored is not None:
        return f"the constant fit {text} was refused: {one_line(stored.error or '')}"
    if lms not in point.tables:
        return f"the constant fit {text} is not stored and there is no orbit table {lms}"
    row = identify_point(point, lms, spec.model, CONSTANT.text, spec.method)
    if row.identification is None:
        return f"the constant fit {text} is refused: {one_line(row.error or '')}"
    result = row.identification.to_dict(fit=False)
    combined = _combined_u(row.identification, point.tables[lms], chosen.get("uncertainty") or {}, result)
    if combined is not None:
        result["expanded_uncertainty"] = combined
        missing = runout_left_out(row.identification, chosen.get("uncertainty") or {})
        result["warnings"] = list(result.get("warnings") or []) + ([missing] if missing else [])
        values = {k: v for k, v in result["coefficients"].items() if v is not None}
        result["not_determined"] = not_determined(values, combined["values"])
    return result, f"{text} (not stored: fitted here from the orbit table)"


def _combined_u(
    ident: Identification, table: OrbitTable, budget: dict[str, Any], result: dict[str, Any]
) -> dict[str, Any] | None:
    """``expanded_uncertainty`` of a fit made here, as the sweep stores it: each coefficient's k
    times its combined standard uncertainty, its covariance plus the calibration part of a stored
    budget's parameters (``sources``, their stated ``source_std``; its runout term when it is
    this fit's, else the fit warns: quality.runout_left_out); None without them. k as the sweep
    takes it, from the budget's ``source_dof`` (quality.budget_coverage); a budget stored before
    those keeps its largest k (``k``), at least the fit's own statistical k, and says so in ``k_rule``."""
    cov = budget_covariance(ident, table, budget)
    if cov is None:
        return None
    std = ident.spec.expand(np.sqrt(np.clip(np.diag(cov), 0, None)))
    ks = budget_coverage(ident, table, budget)
    rule = K_REBUILT
    if ks is None:
        ks, rule = dict.fromkeys(std, max(_num(budget.get("k", COVERAGE_K)), coverage_of(result))), K_LARGEST
    values = {n: ks[n] * float(v) for n, v in std.items()}
    return {
        "k": max(ks.values()),
        "k_values": ks,
        "k_rule": rule,
        "basis": UncertaintyBasis.COMBINED.value,
        "values": values,
    }


#: ``k_rule`` of a constant fit made here: how its U's k was taken
K_REBUILT = (
    "each coefficient's Student's t at 95.45 % at its effective dof, from the budget's source_dof (as the sweep)"
)
K_LARGEST = (
    "the chosen fit's largest stored k (at least this fit's statistical k) for every coefficient: its budget was "
    "stored without source_dof, so the effective dof cannot be rebuilt"
)


def point_speed(point: Point, lms: LoadSystem, spec: FitSpec) -> dict[str, Any] | str:
    """One point's coefficients for ROSS at its spin (rad/s), with U and which fit, or why none."""
    stored = point.identification(lms, spec.model, spec.freq_dep, spec.method)
    if stored is None:
        return f"fit {spec.text(lms)} not stored"
    if stored.result is None:
        return f"fit {spec.text(lms)} was refused: {one_line(stored.error or '')}"
    omega, whirl = point.settings.spin, tested_frequencies(point)
    lo, hi = (float(whirl[0]), float(whirl[-1])) if whirl.size else (math.nan, math.nan)
    tested = f"the tested whirl range {lo:.6g}..{hi:.6g} rad/s"
    result, fit, at = stored.result, spec.text(lms), None
    if is_constant(spec.freq_dep):
        why = "a constant fit"
    elif lo * (1 - 1e-9) <= omega <= hi * (1 + 1e-9):
        at, why = omega, f"synchronous whirl Omega = omega, within {tested}"
    else:
        got = _constant_fit(point, lms, spec, stored.result)
        if isinstance(got, str):
            return f"spin {omega:.6g} rad/s outside {tested} of {spec.text(lms)}, and {got}"
        (result, fit), why = got, f"omega outside {tested}: the constant fit"
    values, U = coefficients_at(result, at or 0.0), uncertainties_at(result, at or 0.0)
    basis = uncertainty_basis(result)
    bounded = at is not None and basis == UncertaintyBasis.COMBINED
    return {
        "point": point.index,
        "label": point.settings.label,
        "condition": [float(f"{getattr(point.settings, c):.9g}") for c in CONDITION],
        "spin": omega,
        "whirl_range": [lo, hi],
        "used": "constant" if at is None else "synchronous",
        "fit": fit,
        "whirl": at,
        "why": why,
        "basis": basis.value + (", calibration part bounded" if bounded else ""),
        "fit_not_determined": list(result.get("not_determined") or []),
        "fit_warnings": speed_warnings(result),
        "values": values,
        "U": U,
        **({"k_rule": rule} if (rule := (result.get("expanded_uncertainty") or {}).get("k_rule")) else {}),
    }
