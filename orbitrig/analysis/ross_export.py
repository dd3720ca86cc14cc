"""A run's identified bearings as ROSS ``BearingElement`` data (``orbitrig export --format ross``).

ROSS evaluates a bearing's coefficients at the rotor speed (``Rotor.A``: frequency = speed), so
the axis is the journal spin omega of the operating points (rad/s), not the whirl frequency
Omega the rig varies within a point. Each complete point and load measuring system gives, from
the chosen stored fit (default kcd11, constant, ols), the coefficients at the synchronous whirl
Omega = omega when the fit is frequency dependent and omega lies in the point's tested whirl
range, else those of the constant fit of the same model and method (stored, else fitted here
from the orbit table, its U on the calibration of the chosen fit's stored budget). The points of
one test condition (CONDITION) form one bearing over speed.
Each coefficient at each speed carries U: the fit's U (orbitrig.store.fit_record) for a constant
fit; for a sum over orders the statistical covariance propagated plus the calibration parts taken
as fully correlated (an upper bound: the run stores no calibration covariance). U > |value| is
listed in ``not_determined`` and warned about, and so is each speed's fit's own warnings
(``fit_warnings``, orbitrig.analysis.ross_warnings). ``bearing_elements`` holds the end values
outside the speeds (ROSS's own spline or interp1d would extrapolate). Fields: docs/catalog.md.

Conventions: the bearing force on the journal is f = -(K d + C d' + M d'') for a journal
displacement d = (x, y), the rig's f = -Z d with Z = K + i Omega C - Omega^2 D; so ROSS
kij = Kij, cij = Cij, mij = Dij (the apparent mass), i the force and j the displacement direction.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from orbitrig.analysis.reduce import identify_point
from orbitrig.analysis.ross_warnings import ROSS_LETTERS, bearing_warnings, notes, speed_warnings, warn_or_refuse
from orbitrig.errors import OrbitrigError
from orbitrig.load_systems import LoadSystem
from orbitrig.store.csvfile import one_line
from orbitrig.store.durable import write_atomic
from orbitrig.store.fit_record import coverage_of, expanded_uncertainty, uncertainty_basis
from orbitrig.store.stored_run import Point, Run
from orbitrig.store.selection import Selection, select_points
from reduction.methods import Method
from reduction.statistics import not_determined
from reduction.result import Identification
from reduction.systematic import UncertaintyBasis, combined_covariance
from reduction.table import OrbitTable

FILE = "ross_bearings.json"
FORMAT = "orbitrig-ross/2"
ENTRIES = ("xx", "xy", "yx", "yy")
KEYS = tuple(f"{c}{e}" for c in "kcm" for e in ENTRIES)  # ROSS's names
HOLD_SPEED = 1.0e5  # rad/s: bearing_elements repeats the end values here (and at 0)
CONDITION = ("recess_pressure", "pressure_ratio", "static_eccentricity", "dynamic_eccentricity")  # a bearing's, SI
CONVENTIONS = {
    "force": "f = -(K d + C d' + M d'') on the journal, d = (x, y) journal displacement, SI",
    "kij, cij, mij": "force in i per displacement (velocity, acceleration) in j; N/m, N s/m, kg",
    "m": "apparent (added) mass: the identified D (0 for a model without D, its U null)",
    "frequency": "rotor speed: the journal spin omega of each operating point, rad/s, ascending "
    "(ROSS evaluates a bearing at the rotor speed)",
    "coefficients": "at each speed the fit at the synchronous whirl Omega = omega when it is frequency "
    "dependent and omega lies in the point's tested whirl range, else the constant fit; 'speeds' says which",
    "outside": "the end values hold below the lowest and above the highest speed (bearing_elements); "
    "ROSS's own interpolation of these arrays would extrapolate",
    "U": "expanded uncertainty of each coefficient at each speed (k of the fit, 2 with a known covariance)",
    "not_determined": "coefficients with U > |value| or U unknown: exported as identified, flagged",
    "fit_warnings": "the warnings of the fit that gave each speed, as stored (chi2, conditioning, ...), and an "
    "adequacy test that does not support the frequency dependence exported: exported as identified, flagged",
}


class FitNotStoredError(OrbitrigError):
    """No selected point gives the fit asked for (the message names it and the fits there are)."""


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


@dataclass
class RossExport:
    """The file written and the points selected (the skipped ones named, with why)."""

    path: Path
    selection: Selection


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
    upper bound); NaN without a covariance."""
    U = expanded_uncertainty(result)
    terms: dict[str, list[tuple[str, int]]] = {}
    for name in result["coefficients"]:
        key, order = _ross_key(name)
        terms.setdefault(key, []).append((name, order))
    free, cov = list(result.get("free") or []), result.get("covariance")
    combined = uncertainty_basis(result) == UncertaintyBasis.COMBINED
    systematic = (result.get("uncertainty") or {}).get("systematic") or {} if combined else {}
    stored_k = (result.get("expanded_uncertainty") or {}).get("k") or (result.get("uncertainty") or {}).get("k")
    k = float(stored_k) if stored_k else coverage_of(result)
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
        out[key] = k * math.sqrt(max(var, 0.0) + sys**2)
    return out


def _constant_fit(
    point: Point, lms: LoadSystem, spec: FitSpec, chosen: dict[str, Any]
) -> tuple[dict[str, Any], str] | str:
    """The constant fit of ``spec``'s model and method (stored, else fitted from the orbit
    table, its U on the calibration uncertainty of the ``chosen`` fit's budget when it has one)
    and its ``--fit`` text, or why there is none."""
    text = spec.text(lms, "none")
    stored = point.identification(lms, spec.model, "none", spec.method)
    if stored is not None and stored.result is not None:
        return stored.result, text
    if stored is not None:
        return f"the constant fit {text} was refused: {one_line(stored.error or '')}"
    if lms not in point.tables:
        return f"the constant fit {text} is not stored and there is no orbit table {lms}"
    row = identify_point(point, lms, spec.model, "none", spec.method)
    if row.identification is None:
        return f"the constant fit {text} is refused: {one_line(row.error or '')}"
    result = row.identification.to_dict(fit=False)
    combined = _combined_u(row.identification, point.tables[lms], chosen.get("uncertainty") or {}, result)
    if combined is not None:
        result["expanded_uncertainty"] = combined
        values = {k: v for k, v in result["coefficients"].items() if v is not None}
        result["not_determined"] = not_determined(values, combined["values"])
    return result, f"{text} (not stored: fitted here from the orbit table)"


def _combined_u(
    ident: Identification, table: OrbitTable, budget: dict[str, Any], result: dict[str, Any]
) -> dict[str, Any] | None:
    """``expanded_uncertainty`` of a fit made here, as the sweep stores it: k (the fit's) times
    the combined standard uncertainty, its covariance plus the calibration part of a stored
    budget's parameters (``sources``, their stated ``source_std``); None without them."""
    if not (budget.get("sources") and budget.get("source_std")):
        return None
    cov = combined_covariance(ident, table, list(budget["sources"]), np.asarray(budget["source_std"], dtype=float))
    if cov is None:
        return None
    k = coverage_of(result)
    std = ident.spec.expand(np.sqrt(np.clip(np.diag(cov), 0, None)))
    return {"k": k, "basis": UncertaintyBasis.COMBINED.value, "values": {n: k * float(v) for n, v in std.items()}}


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
    if spec.freq_dep == "none":
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
    }


def _bearing(lms: LoadSystem, spec: FitSpec, speeds: list[dict[str, Any]]) -> dict[str, Any]:
    """One bearing over speed from its points' :func:`point_speed` (ascending spin)."""
    out: dict[str, Any] = {
        "lms": lms,
        "model": spec.model,
        "freq_dep": spec.freq_dep,
        "method": spec.method,
        "condition": dict(zip(CONDITION, speeds[0]["condition"])),
        "points": [s["point"] for s in speeds],
        "frequency": [s["spin"] for s in speeds],
    }
    for key in KEYS:
        out[key] = [s["values"][key] for s in speeds]
    out["U"] = {key: [s["U"][key] for s in speeds] for key in KEYS}
    lo, hi = out["frequency"][0], out["frequency"][-1]
    out["outside"] = (
        f"one speed ({lo:.6g} rad/s): constant coefficients at every rotor speed"
        if len(speeds) == 1
        else f"end values held below {lo:.6g} and above {hi:.6g} rad/s"
    )
    out["not_determined"] = [
        {"point": s["point"], "spin": s["spin"], "fit": s["fit"], "coefficient": k, "value": s["values"][k], "U": u}
        for s in speeds
        for k, u in ((k, s["U"][k]) for k in not_determined(s["values"], s["U"]))
    ]
    out["fit_warnings"] = bearing_warnings(speeds)
    out["speeds"] = [{k: v for k, v in s.items() if k not in ("values", "U", "condition")} for s in speeds]
    return out


def _fits_there(points: list[Point]) -> list[str]:
    """The usable (not refused) fits the points store, as ``--fit`` text, sorted."""
    return sorted({f"{i.lms}:{i.model}:{i.freq_dep}:{i.method}" for p in points for i in p.identifications if i.ok})


def _collect(run: Run, selection: Selection, spec: FitSpec) -> list[dict[str, Any]]:
    """The bearings of the selected points; each point without the fit (or at a speed its
    condition already has) is named in the selection's ``skipped`` (FitNotStoredError when no
    point has the fit)."""
    groups: dict[tuple[Any, ...], list[dict[str, Any]]] = {}
    missing: list[tuple[Point, str]] = []
    for p in selection.points:
        systems = [spec.lms] if spec.lms else sorted(p.tables)
        if not systems:
            missing.append((p, "no orbit table stored"))
        for lms in systems:
            got = point_speed(p, lms, spec)
            if isinstance(got, str):
                missing.append((p, got if spec.lms else f"{lms}: {got}"))
            else:
                groups.setdefault((lms, *got["condition"]), []).append(got)
    if selection.points and not groups:
        raise FitNotStoredError(_nothing_message(run, selection, spec, [why for _, why in missing]))
    bearings = [_bearing(key[0], spec, _one_per_speed(speeds, selection, missing)) for key, speeds in groups.items()]
    selection.skipped += [f"point {p.name} skipped: {why}" for p, why in missing]
    return bearings


def _one_per_speed(speeds: list[dict[str, Any]], selection: Selection, missing: list) -> list[dict[str, Any]]:
    """``speeds`` by ascending spin; a further point at a spin already taken goes to ``missing``."""
    kept: list[dict[str, Any]] = []
    for s in sorted(speeds, key=lambda s: (s["spin"], s["point"])):
        if not kept or not math.isclose(s["spin"], kept[-1]["spin"], rel_tol=1e-9):
            kept.append(s)
            continue
        why = f"spin {s['spin']:.6g} rad/s and condition as point {kept[-1]['point']:04d}: one value per speed"
        missing.append((next(q for q in selection.points if q.index == s["point"]), f"{why} (choose with --point)"))
    return kept


def _nothing_message(run: Run, selection: Selection, spec: FitSpec, why: list[str]) -> str:
    there = _fits_there(selection.points)
    listing = f"the fits stored: {', '.join(there)}" if there else "no usable fit is stored"
    if all(w.endswith("not stored") for w in why):
        return f"--fit {spec.text()}: not stored in {run.directory} ({listing})"
    return f"--fit {spec.text()}: no point gives it ({'; '.join(dict.fromkeys(why))}); {listing}"


def export_ross(run: Run, out: Path, spec: FitSpec, selection: Selection | None = None) -> RossExport:
    """Write ``out``/ross_bearings.json for the points of ``selection`` (None: every complete
    point; ``spec.lms`` None: every load measuring system). Raises FitNotStoredError when there
    are points but none gives the fit; a point without it is added to the selection's
    ``skipped``, each bearing's speeds, its coefficients not determined and its fit warnings to
    its ``notes``."""
    selection = selection if selection is not None else select_points(run)
    bearings = _collect(run, selection, spec)
    doc = {
        "format": FORMAT,
        "run": str(run.directory),
        "created": run.created,
        "conventions": CONVENTIONS,
        "bearings": bearings,
    }
    path = Path(out) / FILE
    write_atomic(path, (json.dumps(doc, indent=1) + "\n").encode())
    selection.notes += [line for b in bearings for line in notes(b)]
    return RossExport(path, selection)


def held_arrays(frequency: Any, values: dict[str, Any]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The speed axis with 0 and HOLD_SPEED (rad/s) added outside it, and each array with its
    end values repeated there: what bearing_elements gives ROSS."""
    axis = np.asarray(frequency, dtype=float)
    before, after = int(axis[0] > 0), int(axis[-1] < HOLD_SPEED)

    def pad(a: Any, first: Any, last: Any) -> np.ndarray:
        a = np.asarray(a, dtype=float)
        return np.concatenate([np.full(before, first), a, np.full(after, last)])

    return pad(axis, 0.0, HOLD_SPEED), {k: pad(v, v[0], v[-1]) for k, v in values.items()}


def _chosen(doc: dict[str, Any], path: str | Path, point: int | None, lms: str) -> dict[str, Any]:
    found = [b for b in doc["bearings"] if b["lms"] == lms and (point is None or point in b["points"])]
    if not found:
        raise KeyError(
            f"{path}: no bearing of load system {lms!r}" + (f" with point {point}" if point is not None else "")
        )
    if len(found) > 1:
        raise KeyError(
            f"{path}: {len(found)} {lms} bearings (points {[b['points'] for b in found]}): choose one with point="
        )
    return found[0]


def bearing_elements(
    path: str | Path,
    nodes: list[int],
    *,
    point: int | None = None,
    lms: LoadSystem | str = LoadSystem.PIEZO,
    strict: bool = False,
) -> list:
    """ROSS BearingElements at ``nodes`` from an exported file, all with the bearing of ``lms``
    whose points include ``point`` (None: the only one): coefficients over rotor speed,
    piecewise linear between the exported speeds and the end values held outside (one speed:
    constant). A coefficient not determined and a fit warning are warned about (UserWarning),
    with ``strict`` refused (ValueError). Requires ross-rotordynamics: pip install "orbitrig[ross]"."""
    import ross

    data = _chosen(json.loads(Path(path).read_text()), path, point, str(lms))
    warn_or_refuse(data, path, strict)
    if len(data["frequency"]) == 1:
        constant = {k: float(data[k][0]) for k in KEYS}
        return [ross.BearingElement(n=n, tag=f"bearing {n}", **constant) for n in nodes]
    axis, held = held_arrays(data["frequency"], {k: data[k] for k in KEYS})
    elements = []
    for n in nodes:
        element = ross.BearingElement(n=n, frequency=axis, tag=f"bearing {n}", **held)
        for k, v in held.items():  # ROSS's spline would extrapolate (and smooth)
            setattr(element, f"{k}_interpolated", partial(np.interp, xp=axis, fp=v))
        elements.append(element)
    return elements
