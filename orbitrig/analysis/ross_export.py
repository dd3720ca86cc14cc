"""A run's identified bearings as ROSS ``BearingElement`` data (``orbitrig export --format ross``).

For every complete point and load measuring system, the chosen stored fit (default kcd11,
constant, ols) is repeated from the stored orbit table (orbitrig.analysis.reduce.reidentify)
and its K(Omega), C(Omega), D(Omega) are evaluated at the point's tested orbit frequencies
|Omega| (forward whirl, rad/s). One JSON file, ``ross_bearings.json``:

    {"format": "orbitrig-ross/1", "run": ..., "conventions": {...},
     "bearings": [{"point", "label", "lms", "model", "freq_dep", "method", "spin",
                   "frequency": [rad/s], "kxx": [N/m], "kxy", "kyx", "kyy",
                   "cxx": [N s/m], ..., "mxx": [kg], ...}]}

Conventions (docs/catalog.md): the bearing force on the journal is f = -(K d + C d' + M d'')
for a journal displacement d = (x, y), which is the rig's f = -Z d with
Z = K + i Omega C - Omega^2 D; so ROSS kij = Kij, cij = Cij, mij = Dij (the apparent mass),
with i the force and j the displacement direction. ``bearing_elements`` builds the ROSS
elements (ross-rotordynamics, the ``ross`` extra).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from orbitrig.analysis.reduce import reidentify
from orbitrig.load_systems import LoadSystem
from orbitrig.store.durable import write_atomic
from orbitrig.store.reader import Point, Run

FILE = "ross_bearings.json"
FORMAT = "orbitrig-ross/1"
ENTRIES = ("xx", "xy", "yx", "yy")
CONVENTIONS = {
    "force": "f = -(K d + C d' + M d'') on the journal, d = (x, y) journal displacement, SI",
    "kij, cij, mij": "force in i per displacement (velocity, acceleration) in j; N/m, N s/m, kg",
    "m": "apparent (added) mass: the identified D",
    "frequency": "orbit (whirl) frequency |Omega|, rad/s, the point's tested orbit frequencies; "
    "coefficients evaluated for forward whirl",
}


def point_bearing(point: Point, lms: LoadSystem, model: str, freq_dep: str, method: str) -> dict[str, Any] | None:
    """The ROSS data of one point's fit, or None when it was not stored or was refused."""
    stored = point.identification(lms, model, freq_dep)
    if stored is None or not stored.ok or stored.method != method or lms not in point.tables:
        return None
    ident = reidentify(point, stored).identification
    if ident is None:
        return None
    frequency = np.unique(np.abs(point.tables[lms].orbit))
    mats = np.array([ident.matrices(w) for w in frequency])  # (n, 3: K C D, 2, 2)
    out: dict[str, Any] = {
        "point": point.index,
        "label": point.settings.label,
        "lms": lms,
        "model": model,
        "freq_dep": freq_dep,
        "method": method,
        "spin": point.settings.spin,
        "frequency": frequency.tolist(),
    }
    for m, letter in enumerate("kcm"):
        for e, (i, j) in zip(ENTRIES, ((0, 0), (0, 1), (1, 0), (1, 1))):
            out[f"{letter}{e}"] = mats[:, m, i, j].tolist()
    return out


def export_ross(
    run: Run,
    out: Path,
    *,
    lms: LoadSystem | None = LoadSystem.PIEZO,
    model: str = "kcd11",
    freq_dep: str = "none",
    method: str = "ols",
) -> Path:
    """Write ``out``/ross_bearings.json for every complete point (``lms`` None: every load
    measuring system); returns the file."""
    bearings = [
        b
        for p in run.complete_points
        for name in ([lms] if lms else sorted(p.tables))
        if (b := point_bearing(p, name, model, freq_dep, method)) is not None
    ]
    doc = {
        "format": FORMAT,
        "run": str(run.directory),
        "created": run.created,
        "conventions": CONVENTIONS,
        "bearings": bearings,
    }
    path = Path(out) / FILE
    write_atomic(path, (json.dumps(doc, indent=1) + "\n").encode())
    return path


def bearing_elements(
    path: str | Path, nodes: list[int], *, point: int = 0, lms: LoadSystem | str = LoadSystem.PIEZO
) -> list:
    """ROSS BearingElements at ``nodes`` from an exported file, all with the bearing of
    ``point`` / ``lms`` (requires ross-rotordynamics: pip install "orbitrig[ross]")."""
    import ross

    doc = json.loads(Path(path).read_text())
    data = next((b for b in doc["bearings"] if b["point"] == point and b["lms"] == lms), None)
    if data is None:
        raise KeyError(f"{path}: no bearing of point {point} and load system {str(lms)!r}")
    coefficients = {k: np.asarray(data[k]) for k in (f"{c}{e}" for c in "kcm" for e in ENTRIES)}
    return [
        ross.BearingElement(n=n, frequency=np.asarray(data["frequency"]), tag=f"bearing {n}", **coefficients)
        for n in nodes
    ]
