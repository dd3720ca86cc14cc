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
(``fit_warnings``, orbitrig.analysis.ross_warnings). One point's speed is orbitrig.analysis.ross_speed's;
``bearing_elements`` (orbitrig.analysis.ross_elements) holds the end values outside the speeds
(ROSS's own spline or interp1d would extrapolate). Fields: docs/catalog.md.

Conventions: the bearing force on the journal is f = -(K d + C d' + M d'') for a journal
displacement d = (x, y), the rig's f = -Z d with Z = K + i Omega C - Omega^2 D; so ROSS
kij = Kij, cij = Cij, mij = Dij (the apparent mass), i the force and j the displacement direction.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from orbitrig.analysis.ross_warnings import UNITS, bearing_warnings, notes
from orbitrig.errors import OrbitrigError
from orbitrig.load_systems import LoadSystem
from orbitrig.store.durable import write_atomic
from orbitrig.store.layout import point_name
from orbitrig.store.stored_run import Point, Run
from orbitrig.store.selection import Selection, select_points
from reduction.statistics import not_determined
from orbitrig.analysis.ross_speed import CONDITION, KEYS, FitSpec, point_speed

FILE = "ross_bearings.json"
FORMAT = "orbitrig-ross/2"
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
    "U": "expanded uncertainty of each coefficient at each speed (k of the fit, 2 with a known covariance); "
    "null: the model has not the coefficient (m of kc7) or its U could not be estimated (then in not_determined)",
    "not_determined": "coefficients with U > |value| or U unknown: exported as identified, flagged",
    "fit_warnings": "the warnings of the fit that gave each speed, as stored (chi2, conditioning, ...), and an "
    "adequacy test that does not support the frequency dependence exported: exported as identified, flagged",
}

#: each numeric field's unit, as pint parses it (U, not_determined's value and U: the coefficient's)
FIELD_UNITS = {
    "frequency": "rad/s",
    **{key: UNITS[key[0]] for key in KEYS},
    "recess_pressure": "Pa",
    **{c: "1" for c in CONDITION if c != "recess_pressure"},
    "spin": "rad/s",
    "whirl": "rad/s",
    "whirl_range": "rad/s",
}


class FitNotStoredError(OrbitrigError):
    """No selected point gives the fit asked for (the message names it and the fits there are)."""


@dataclass
class RossExport:
    """The file written and the points selected (the skipped ones named, with why)."""

    path: Path
    selection: Selection


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
        why = f"spin {s['spin']:.6g} rad/s and condition as point {point_name(kept[-1]['point'])}: one value per speed"
        missing.append((next(q for q in selection.points if q.index == s["point"]), f"{why} (choose with --point)"))
    return kept


def _nothing_message(run: Run, selection: Selection, spec: FitSpec, why: list[str]) -> str:
    there = _fits_there(selection.points)
    listing = f"the fits stored: {', '.join(there)}" if there else "no usable fit is stored"
    if all(w.endswith("not stored") for w in why):
        return f"--fit {spec.text()}: not stored in {run.directory} ({listing})"
    return f"--fit {spec.text()}: no point gives it ({'; '.join(dict.fromkeys(why))}); {listing}"


def _strict(value: Any) -> Any:
    """``value`` for strict JSON (jq, JSON.parse, Octave's jsondecode): a non-finite number (a U
    that could not be estimated) null."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _strict(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_strict(v) for v in value]
    return value


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
        "units": FIELD_UNITS,
        "bearings": bearings,
    }
    path = Path(out) / FILE
    write_atomic(path, (json.dumps(_strict(doc), indent=1, allow_nan=False) + "\n").encode())
    selection.notes += [line for b in bearings for line in notes(b)]
    return RossExport(path, selection)
