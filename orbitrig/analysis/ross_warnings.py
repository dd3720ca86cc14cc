"""What the ROSS export (orbitrig.analysis.ross_export) warns about: per speed the warnings of
the fit that gave it, as the run stores them (a chi2 that does not fit the stated u_*,
ill-conditioning, ...) and a frequency dependence its adequacy test does not support; per
bearing every coefficient not determined (U > |value|). The export prints them on standard
error; ``bearing_elements`` warns (UserWarning) or, strict, refuses (ValueError)."""

from __future__ import annotations

import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from orbitrig.store.layout import point_name
from rigunits import COEFFICIENT_UNITS


#: ROSS's letter of each coefficient matrix (K stiffness, C damping, D inertia: ROSS's m)
ROSS_LETTERS = {"K": "k", "C": "c", "D": "m"}
#: SI unit of each ROSS coefficient by its letter
UNITS = {ross: COEFFICIENT_UNITS[matrix] for matrix, ross in ROSS_LETTERS.items()}


def speed_warnings(result: dict[str, Any]) -> list[str]:
    """The stored fit ``result``'s warnings and, when its adequacy test does not support its
    frequency dependence, that verdict."""
    out = [str(w) for w in result.get("warnings") or []]
    adequacy = result.get("adequacy") or {}
    if adequacy.get("supported") is False:
        out.append(
            f"adequacy ({adequacy.get('test', '')}): {adequacy.get('verdict', '')}; "
            "the frequency dependence exported is not supported"
        )
    return out


def bearing_warnings(speeds: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Every speed's ``fit_warnings``, each with its point, spin (rad/s) and fit."""
    return [
        {"point": s["point"], "spin": s["spin"], "fit": s["fit"], "warning": w}
        for s in speeds
        for w in s["fit_warnings"]
    ]


def notes(bearing: dict[str, Any]) -> list[str]:
    """What the export tells on standard error about one bearing: its speeds, which fit gave
    each, every coefficient not determined and every fit warning."""
    used = ", ".join(f"{s['spin']:.6g} rad/s {s['used']} ({s['fit']})" for s in bearing["speeds"])
    points = ", ".join(point_name(i) for i in bearing["points"])  # as the warnings below (the file: [3, 4])
    point_s = "point" if len(bearing["points"]) == 1 else "points"
    lines = [f"ross: {bearing['lms']} bearing of {point_s} {points}: {used}; {bearing['outside']}"]
    for n in bearing["not_determined"]:
        unit = _unit(n)
        lines.append(
            f"warning: point {point_name(n['point'])} at {n['spin']:.6g} rad/s, fit {n['fit']}: {n['coefficient']} = "
            f"{n['value']:.4g} {unit} with {_u_text(n['U'], unit)} is not determined; "
            "exported as identified and listed in not_determined"
        )
    lines += [
        f"warning: point {point_name(w['point'])} at {w['spin']:.6g} rad/s, fit {w['fit']}: {w['warning']}"
        for w in bearing.get("fit_warnings") or []
    ]
    return lines


def _u_text(u: float | None, unit: str) -> str:
    """'U = 4.1e+06 N/m (U > |value|)', or 'U unknown (not estimated)' for a U the file holds as
    null (a NaN before the file was strict JSON)."""
    if u is None or not math.isfinite(u):
        return "U unknown (not estimated)"
    return f"U = {u:.4g} {unit} (U > |value|)"


def _unit(flagged: dict[str, Any]) -> str:
    """The SI unit of a coefficient not determined (ROSS's name: kxy, cxx, myy)."""
    return UNITS[flagged["coefficient"][0]]


def warn_or_refuse(data: dict[str, Any], path: str | Path, strict: bool) -> None:
    """Warn (UserWarning, one per kind) about a bearing's coefficients not determined and its
    fit warnings; with ``strict`` refuse them (ValueError naming each). A file written before
    fit warnings were exported has none."""
    flagged = [
        f"point {point_name(n['point'])} ({n['spin']:.6g} rad/s), fit {n['fit']}: {n['coefficient']} = {n['value']:.4g} "
        f"{_unit(n)} with {_u_text(n['U'], _unit(n))}"
        for n in data.get("not_determined") or []
    ]
    fits = [
        f"point {point_name(w['point'])} ({w['spin']:.6g} rad/s), fit {w['fit']}: {w['warning']}"
        for w in data.get("fit_warnings") or []
    ]
    messages = (
        [f"{path}: coefficients not determined (U > |value| or U unknown): " + "; ".join(flagged)] if flagged else []
    )
    messages += [f"{path}: fit warnings: " + "; ".join(fits)] if fits else []
    if strict and messages:
        raise ValueError("\n".join(messages))
    for message in messages:
        warnings.warn(message, UserWarning, stacklevel=3)


def mass_warning(data: dict[str, Any], path: str | Path, nodes: list[int]) -> str | None:
    """What ``bearing_elements`` warns of a bearing whose apparent mass matrix [[mxx, mxy], [myx,
    myy]] (kg) is not positive at some speed (a compressible film's, say), None when it is at every
    speed: ROSS adds it to the mass of each node given, and a node lighter than its magnitude makes
    the rotor's mass matrix indefinite, whose state matrix then has a spurious root of positive real
    part (a divergence at once) that run_modal's list of modes leaves out."""
    m = np.array([[data["mxx"], data["mxy"]], [data["myx"], data["myy"]]], dtype=float).transpose(2, 0, 1)
    lowest = np.linalg.eigvalsh((m + m.transpose(0, 2, 1)) / 2)[:, 0]  # per speed, kg
    at = int(np.argmin(lowest))
    if lowest[at] >= 0:
        return None
    low = float(lowest[at])
    return (
        f"{path}: apparent mass not positive: at {data['frequency'][at]:.6g} rad/s [[mxx, mxy], [myx, myy]] has "
        f"the eigenvalue {low:.4g} kg; ROSS adds it to the mass of node(s) {', '.join(map(str, nodes))}, and a node "
        f"whose own mass (shaft, disks) is below {-low:.4g} kg makes the rotor's mass matrix indefinite: its state "
        "matrix then has a spurious eigenvalue of positive real part (a divergence), which run_modal's modes do "
        "not list; check rotor.M(speed) there, or give ROSS the bearing with m = 0 (the file's mxx ... myy set to 0)"
    )
