"""Predicted coefficients (for example a bulk-flow code's table) from a CSV file.

Columns (header row; order free; docs/catalog.md):
- conditions, any of: ``spin_rpm``, ``recess_pressure_mpa``, ``pressure_ratio``,
  ``static_eccentricity``, ``dynamic_eccentricity`` (the compared variable is required);
- coefficients, any of ``Kxx [N/m]`` ... ``Kyy [N/m]``, ``Cxx [N s/m]`` ... ``Dyy [kg]``
  (the unit in brackets must be the SI one shown); an empty cell is no prediction.
Lines starting with ``#`` are comments. Only the lines whose given conditions (all but the
compared variable; an empty or absent one agrees with any) are those of a plotted row are
drawn, one dashed line per set of conditions (`predicted_lines`).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

from orbitrig.catalog.compare import Row, Variable, condition_value
from orbitrig.catalog.errors import CatalogUsageError
from orbitrig.catalog.rows import COEFFICIENTS, UNITS
from rigunits import MPA

CONDITION_COLUMNS = ("spin_rpm", "recess_pressure_mpa", "pressure_ratio", "static_eccentricity", "dynamic_eccentricity")
#: condition column -> (catalog column, factor to the catalog's unit: MPa -> Pa)
CATALOG_CONDITION = {c: (c, 1.0) for c in CONDITION_COLUMNS} | {"recess_pressure_mpa": ("recess_pressure", MPA)}
#: prediction lines by their given conditions: ((catalog column, value), ...), lines
PredictedLines = list[tuple[tuple[tuple[str, float], ...], list[dict[str, float]]]]


class PredictedError(CatalogUsageError):
    """A malformed predicted-coefficients CSV; the message names file, line and column."""


def _column(name: str, file: Path, line: int) -> str:
    name = name.strip()
    if name in CONDITION_COLUMNS:
        return name
    key, _, unit = name.partition(" [")
    if key in COEFFICIENTS and unit == f"{UNITS[key[0]]}]":
        return key
    if key in COEFFICIENTS:
        raise PredictedError(
            f"{file}, line {line}, column {name!r}: the unit of {key} is {UNITS[key[0]]!r} (SI): "
            f"write '{key} [{UNITS[key[0]]}]' and the values in {UNITS[key[0]]}"
        )
    raise PredictedError(
        f"{file}, line {line}, column {name!r}: not one of {', '.join(CONDITION_COLUMNS)} "
        f"or 'KEY [unit]' (e.g. 'Kxx [N/m]', 'Cxy [N s/m]', 'Dxx [kg]')"
    )


def _lines(path: Path) -> list[tuple[int, list[str]]]:
    """(line number in the file, cells) of each line but the comments; a UTF-8 byte order
    mark (Excel's "CSV UTF-8") is dropped."""
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as err:
        raise PredictedError(f"{path}: cannot read ({err})") from None
    return [
        (number, next(csv.reader([line]), []))
        for number, line in enumerate(text.splitlines(), start=1)
        if not line.lstrip().startswith("#")
    ]


def read_predicted(path: Path, against: Variable | None = None) -> list[dict[str, float]]:
    """One dict per line: condition and coefficient name -> value (SI coefficients, NaN if empty).
    ``against``: the compared variable, whose column the file must have."""
    path = Path(path)
    lines = _lines(path)
    at, cells = lines[0] if lines else (1, [])
    header = [_column(name, path, at) for name in cells]
    twice = next((cells[k] for k, name in enumerate(header) if name in header[:k]), None)
    if twice is not None:  # else the last one would silently win
        raise PredictedError(f"{path}, line {at}, column {twice.strip()!r}: the column appears twice in the header")
    if not any(name in COEFFICIENTS for name in header):
        raise PredictedError(f"{path}, line {at}: no coefficient column (e.g. 'Kxx [N/m]')")
    if against is not None and against.predicted_column not in header:
        raise PredictedError(
            f"{path}, line {at}: no column {against.predicted_column!r} (needed for --against {against})"
        )
    out = []
    for number, cells in lines[1:]:
        if len(cells) != len(header):
            raise PredictedError(f"{path}, line {number}: {len(cells)} cells for {len(header)} columns")
        out.append({name: _value(cell, path, number, name) for name, cell in zip(header, cells)})
    return out


def _value(cell: str, path: Path, line: int, column: str) -> float:
    if not cell.strip():
        return math.nan
    try:
        value = float(cell)
    except ValueError:
        raise PredictedError(f"{path}, line {line}, column {column!r}: {cell!r} is not a number") from None
    if not math.isfinite(value):  # an inf would be drawn off the axes; a written nan reads as a value
        raise PredictedError(
            f"{path}, line {line}, column {column!r}: {cell!r} is not a finite number (an empty cell is no prediction)"
        )
    return value


def _conditions(line: dict[str, float], variable: Variable) -> tuple[tuple[str, float], ...]:
    """The line's given conditions but the compared variable: (catalog column, value in its unit)."""
    return tuple(
        (column, condition_value(line[name] * factor))
        for name, (column, factor) in CATALOG_CONDITION.items()
        if name != variable.predicted_column and math.isfinite(line.get(name, math.nan))
    )


def predicted_lines(predicted: list[dict[str, float]], rows: list[Row], variable: Variable) -> PredictedLines:
    """The prediction lines agreeing with a plotted row (module docstring), grouped by their
    conditions: (conditions, lines) in the order of the file."""
    columns = {column for column, _ in CATALOG_CONDITION.values()}
    plotted = [{c: condition_value(v) for c, v in row.items() if c in columns and v is not None} for row in rows]
    out: dict[tuple[tuple[str, float], ...], list[dict[str, float]]] = {}
    for line in predicted:
        given = _conditions(line, variable)
        if any(all(row.get(c) == v for c, v in given) for row in plotted):
            out.setdefault(given, []).append(line)
    return list(out.items())
