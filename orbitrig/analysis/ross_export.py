"""A run's identified bearings as ROSS ``BearingElement`` data (``orbitrig export --format ross``).

For every complete point and load measuring system, the chosen stored fit (default kcd11,
constant, ols) is repeated from the stored orbit table (orbitrig.analysis.reduce.reidentify)
and its K(Omega), C(Omega), D(Omega) are evaluated at the point's tested orbit frequencies:
the planned |Omega| of each tested orbit ratio, once (ascending, rad/s, forward whirl), the
frequencies the sweep's derived quantities are evaluated at (the fit itself regresses each
row at its measured speed, which differs slightly between the two whirl directions). One
JSON file, ``ross_bearings.json``:

    {"format": "orbitrig-ross/1", "run": ..., "conventions": {...},
     "bearings": [{"point", "label", "lms", "model", "freq_dep", "method", "spin",
                   "frequency": [rad/s], "kxx": [N/m], "kxy", "kyx", "kyy",
                   "cxx": [N s/m], ..., "mxx": [kg], ...}]}

A fit no selected point stores is a FitNotStoredError naming the fits there are; a point
without it (not stored, refused, no orbit table) is skipped and named.

Conventions (docs/catalog.md): the bearing force on the journal is f = -(K d + C d' + M d'')
for a journal displacement d = (x, y), which is the rig's f = -Z d with
Z = K + i Omega C - Omega^2 D; so ROSS kij = Kij, cij = Cij, mij = Dij (the apparent mass),
with i the force and j the displacement direction. ``bearing_elements`` builds the ROSS
elements (ross-rotordynamics, the ``ross`` extra).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from orbitrig.analysis.reduce import reidentify
from orbitrig.errors import OrbitrigError
from orbitrig.load_systems import LoadSystem
from orbitrig.store.csvfile import one_line
from orbitrig.store.durable import write_atomic
from orbitrig.store.reader import Point, Run
from orbitrig.store.selection import Selection, select_points
from reduction.methods import Method

FILE = "ross_bearings.json"
FORMAT = "orbitrig-ross/1"
ENTRIES = ("xx", "xy", "yx", "yy")
CONVENTIONS = {
    "force": "f = -(K d + C d' + M d'') on the journal, d = (x, y) journal displacement, SI",
    "kij, cij, mij": "force in i per displacement (velocity, acceleration) in j; N/m, N s/m, kg",
    "m": "apparent (added) mass: the identified D",
    "frequency": "orbit (whirl) frequency |Omega|, rad/s: the point's planned orbit frequencies, "
    "one per tested orbit ratio, ascending; coefficients evaluated for forward whirl",
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

    def text(self, lms: LoadSystem | None = None) -> str:
        """``LMS:MODEL:FREQ_DEP:METHOD`` (the form of ``--fit``)."""
        return f"{lms or self.lms or ''}:{self.model}:{self.freq_dep}:{self.method}"


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
    return np.unique(np.concatenate([np.abs(t.orbit) for t in point.tables.values()]))


def point_bearing(point: Point, lms: LoadSystem, spec: FitSpec) -> dict[str, Any] | str:
    """The ROSS data of one point's fit, or why the point has none."""
    stored = point.identification(lms, spec.model, spec.freq_dep, spec.method)
    if stored is None:
        return f"fit {spec.text(lms)} not stored"
    if not stored.ok:
        return f"fit {spec.text(lms)} was refused: {one_line(stored.error or '')}"
    if lms not in point.tables:
        return f"no orbit table {lms}"
    row = reidentify(point, stored)
    if row.identification is None:
        return f"fit {spec.text(lms)} cannot be repeated from the stored orbit table: {one_line(row.error or '')}"
    frequency = tested_frequencies(point)
    mats = np.array([row.identification.matrices(w) for w in frequency])  # (n, 3: K C D, 2, 2)
    out: dict[str, Any] = {
        "point": point.index,
        "label": point.settings.label,
        "lms": lms,
        "model": spec.model,
        "freq_dep": spec.freq_dep,
        "method": spec.method,
        "spin": point.settings.spin,
        "frequency": frequency.tolist(),
    }
    for m, letter in enumerate("kcm"):
        for e, (i, j) in zip(ENTRIES, ((0, 0), (0, 1), (1, 0), (1, 1))):
            out[f"{letter}{e}"] = mats[:, m, i, j].tolist()
    return out


def _fits_there(points: list[Point]) -> list[str]:
    """The usable (not refused) fits the points store, as ``--fit`` text, sorted."""
    return sorted({f"{i.lms}:{i.model}:{i.freq_dep}:{i.method}" for p in points for i in p.identifications if i.ok})


def _collect(run: Run, selection: Selection, spec: FitSpec) -> list[dict[str, Any]]:
    """The bearings of the selected points; each point without the fit is named in the
    selection's ``skipped`` (FitNotStoredError when no point has it)."""
    bearings: list[dict[str, Any]] = []
    missing: list[tuple[Point, str]] = []
    for p in selection.points:
        systems = [spec.lms] if spec.lms else sorted(p.tables)
        if not systems:
            missing.append((p, "no orbit table stored"))
        for lms in systems:
            got = point_bearing(p, lms, spec)
            if isinstance(got, str):
                missing.append((p, got if spec.lms else f"{lms}: {got}"))
            else:
                bearings.append(got)
    if selection.points and not bearings:
        raise FitNotStoredError(_nothing_message(run, selection, spec, [why for _, why in missing]))
    selection.skipped += [f"point {p.name} skipped: {why}" for p, why in missing]
    return bearings


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
    ``skipped``."""
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
    return RossExport(path, selection)


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
