"""Predicted coefficients (for example a bulk-flow code's table) from a CSV file.

Columns (header row; order free; docs/catalog.md):
- conditions, any of: ``spin_rpm``, ``recess_pressure_mpa``, ``pressure_ratio``,
  ``static_eccentricity``, ``dynamic_eccentricity`` (the compared variable is required);
- coefficients, any of ``Kxx [N/m]`` ... ``Kyy [N/m]``, ``Cxx [N s/m]`` ... ``Dyy [kg]``
  (the unit in brackets must be the SI one shown); an empty cell is no prediction.
Lines starting with ``#`` are comments.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

from orbitrig.catalog.compare import Variable
from orbitrig.catalog.errors import CatalogUsageError
from orbitrig.catalog.rows import COEFFICIENTS, UNITS

CONDITION_COLUMNS = ("spin_rpm", "recess_pressure_mpa", "pressure_ratio", "static_eccentricity", "dynamic_eccentricity")


class PredictedError(CatalogUsageError):
    """A malformed predicted-coefficients CSV; the message names file, line and column."""


def _column(name: str, file: Path) -> str:
    name = name.strip()
    if name in CONDITION_COLUMNS:
        return name
    key, _, unit = name.partition(" [")
    if key in COEFFICIENTS and unit == f"{UNITS[key[0]]}]":
        return key
    raise PredictedError(
        f"{file}, line 1, column {name!r}: not one of {', '.join(CONDITION_COLUMNS)} "
        f"or 'KEY [unit]' (e.g. 'Kxx [N/m]', 'Cxy [N s/m]', 'Dxx [kg]')"
    )


def read_predicted(path: Path, against: Variable | None = None) -> list[dict[str, float]]:
    """One dict per line: condition and coefficient name -> value (SI coefficients, NaN if empty).
    ``against``: the compared variable, whose column the file must have."""
    path = Path(path)
    try:
        lines = [line for line in path.read_text(encoding="utf-8").splitlines() if not line.lstrip().startswith("#")]
    except (OSError, UnicodeDecodeError) as err:
        raise PredictedError(f"{path}: cannot read ({err})") from None
    reader = csv.reader(lines)
    header = [_column(name, path) for name in next(reader, [])]
    if not any(name in COEFFICIENTS for name in header):
        raise PredictedError(f"{path}, line 1: no coefficient column (e.g. 'Kxx [N/m]')")
    if against is not None and against.predicted_column not in header:
        raise PredictedError(f"{path}, line 1: no column {against.predicted_column!r} (needed for --against {against})")
    out = []
    for number, cells in enumerate(reader, start=2):
        if len(cells) != len(header):
            raise PredictedError(f"{path}, line {number}: {len(cells)} cells for {len(header)} columns")
        out.append({name: _value(cell, path, number, name) for name, cell in zip(header, cells)})
    return out


def _value(cell: str, path: Path, line: int, column: str) -> float:
    if not cell.strip():
        return math.nan
    try:
        return float(cell)
    except ValueError:
        raise PredictedError(f"{path}, line {line}, column {column!r}: {cell!r} is not a number") from None
