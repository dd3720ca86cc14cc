"""ROSS ``BearingElement``s from an exported ross_bearings.json (orbitrig.analysis.ross_export):
coefficients over rotor speed omega (rad/s), piecewise linear between the exported speeds and the
end values held outside them (0 and ``HOLD_SPEED``); one speed: constant coefficients.
Requires ross-rotordynamics: pip install -e ".[ross]" in orbitrig's source tree.
"""

from __future__ import annotations

import json
import warnings
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from orbitrig.analysis.ross_warnings import mass_warning, warn_or_refuse
from orbitrig.errors import ExportFileError
from orbitrig.load_systems import LoadSystem
from orbitrig.analysis.ross_speed import KEYS
from orbitrig.store.strict_json import once_each

HOLD_SPEED = 1.0e5  # rad/s: bearing_elements repeats the end values here (and at 0)


def import_ross() -> Any:
    """The ``ross`` module, imported with the interpreter's warning format kept: a dependency of
    ROSS (plotly.tools) replaces ``warnings.formatwarning`` on import, which would print every later
    warning of the process as "file:line: Category:", a blank line, then the message."""
    kept = warnings.formatwarning
    try:
        import ross
    finally:
        warnings.formatwarning = kept
    return ross


def held_arrays(frequency: Any, values: dict[str, Any]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The speed axis with 0 and HOLD_SPEED (rad/s) added outside it, and each array with its
    end values repeated there: what bearing_elements gives ROSS."""
    axis = np.asarray(frequency, dtype=float)
    before, after = int(axis[0] > 0), int(axis[-1] < HOLD_SPEED)

    def pad(a: Any, first: Any, last: Any) -> np.ndarray:
        a = np.asarray(a, dtype=float)
        return np.concatenate([np.full(before, first), a, np.full(after, last)])

    return pad(axis, 0.0, HOLD_SPEED), {k: pad(v, v[0], v[-1]) for k, v in values.items()}


def read_export(path: str | Path) -> dict[str, Any]:
    """The exported ross_bearings.json at ``path`` (or a file of its layout made by hand);
    orbitrig.errors.ExportFileError (a ValueError) naming the file when it is not one: not
    readable, not JSON, a key given twice (readers differ in which counts), nested too deep, or
    JSON of another kind (a run's run.json, say)."""
    try:
        doc = json.loads(Path(path).read_text(encoding="utf-8"), object_pairs_hook=once_each)
    except (UnicodeDecodeError, json.JSONDecodeError) as err:
        raise ExportFileError(path, f"not JSON ({err})") from None
    except ValueError as err:  # once_each: a key given twice
        raise ExportFileError(path, f"not an orbitrig ROSS export ({err})") from None
    except RecursionError:
        raise ExportFileError(path, "not JSON of an export (nested too deep to read)") from None
    except OSError as err:
        raise ExportFileError(path, f"cannot be read ({err.strerror or err})") from None
    fmt = doc.get("format") if isinstance(doc, dict) else type(doc).__name__
    if fmt is not None and not (isinstance(fmt, str) and fmt.startswith("orbitrig-ross/")):
        why = f"format {fmt!r}"  # a file made by hand in its layout may give none
    elif not isinstance(doc.get("bearings"), list):
        why = "no list 'bearings'"
    else:
        return doc
    raise ExportFileError(
        path, f"not an orbitrig ROSS export ({why}): `orbitrig export RUN --format ross` writes ross_bearings.json"
    )


def _checked(bearing: Any, at: int, path: str | Path) -> dict[str, Any]:
    """``bearing`` (entry ``at`` of the file's ``bearings``) when it has what bearing_elements
    uses: ``lms``, a list ``points``, and ``frequency`` (rad/s, ascending) and every ROSS key
    as lists of numbers of one length; else ExportFileError naming the file, the entry and the field."""
    where = f"bearings[{at}]"
    if not isinstance(bearing, dict):
        raise ExportFileError(path, f"{where}: not an object")
    missing = [k for k in ("lms", "points", "frequency", *KEYS) if k not in bearing]
    if missing:
        raise ExportFileError(path, f"{where}: no field {', '.join(map(repr, missing))}")
    if not isinstance(bearing["points"], list):
        raise ExportFileError(path, f"{where}.points: not a list")
    n = len(bearing["frequency"]) if isinstance(bearing["frequency"], list) else 0
    for key in ("frequency", *KEYS):
        values = bearing[key]
        numbers = isinstance(values, list) and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in values
        )
        if not numbers or not values or len(values) != n:
            raise ExportFileError(path, f"{where}.{key}: not a list of {n or 'one or more'} numbers (one per speed)")
    if any(b <= a for a, b in zip(bearing["frequency"], bearing["frequency"][1:])):
        raise ExportFileError(path, f"{where}.frequency: not ascending (rad/s, one value per speed)")
    return bearing


def _chosen(doc: dict[str, Any], path: str | Path, point: int | None, lms: str) -> dict[str, Any]:
    bearings = [_checked(b, at, path) for at, b in enumerate(doc["bearings"])]
    found = [b for b in bearings if b["lms"] == lms and (point is None or point in b["points"])]
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
    with ``strict`` refused (ValueError); an apparent mass matrix that is not positive is warned
    about (ross_warnings.mass_warning), never refused. A file that is no export, or a bearing in it without
    a field used here, is an ExportFileError (a ValueError) naming the file and the field. Requires ross-rotordynamics: pip install -e ".[ross]" (source tree)."""
    ross = import_ross()
    data = _chosen(read_export(path), path, point, str(lms))
    warn_or_refuse(data, path, strict)
    if negative := mass_warning(data, path, nodes):  # physical, not a reason to distrust the fit: never refused
        warnings.warn(negative, UserWarning, stacklevel=2)
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
