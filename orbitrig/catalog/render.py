"""Catalog rows as text: CSV (column names with units), JSON, and the `list` table."""

from __future__ import annotations

import json
import math
from enum import StrEnum
from typing import Any

from orbitrig.catalog.schema import COLUMN_UNITS, ROW_COLUMNS
from orbitrig.store.csvfile import one_line, render_rows


class ExportFormat(StrEnum):
    CSV = "csv"
    JSON = "json"


#: the columns `catalog list` shows unless told otherwise
LIST_COLUMNS = (
    "run_id",
    "point",
    "lms",
    "model",
    "freq_dep",
    "method",
    "spin_rpm",
    "pressure_ratio",
    "static_eccentricity",
    "dynamic_eccentricity",
    "Kxx",
    "Kxx_U",
    "Cxx",
    "Cxx_U",
    "adequacy_verdict",
)


def header(name: str) -> str:
    """CSV column name with its unit: 'Kxx [N/m]', 'spin [rad/s]', 'orbit_hz [Hz]', 'point';
    'spin_rpm' stays bare (its name says its unit)."""
    unit = COLUMN_UNITS.get(name)
    return f"{name} [{unit}]" if unit and name != "spin_rpm" else name


#: columns the catalog holds as JSON text: values, not strings, in the JSON export
JSON_COLUMNS = ("orbit_hz", "coefficients_json")


def render(rows: list[dict[str, Any]], fmt: ExportFormat) -> bytes:
    """Every column of ``rows``: CSV (empty cell = NULL) or a JSON list of objects (SI; the
    JSON_COLUMNS as the lists and objects they hold)."""
    if fmt is ExportFormat.JSON:
        return (json.dumps([_decoded(r) for r in rows], indent=1, allow_nan=False) + "\n").encode()
    head = [header(c) for c in ROW_COLUMNS]
    return render_rows([head, *(["" if row.get(c) is None else _cell(row[c]) for c in ROW_COLUMNS] for row in rows)])


def _decoded(row: dict[str, Any]) -> dict[str, Any]:
    """The row for strict JSON: a non-finite number (PostgreSQL keeps NaN) null, the JSON_COLUMNS decoded."""
    out: dict[str, Any] = {k: None if isinstance(v, float) and not math.isfinite(v) else v for k, v in row.items()}
    for c in JSON_COLUMNS:
        text = out.get(c)
        if isinstance(text, str):  # a row catalogued before it was strict JSON: NaN -> null
            out[c] = json.loads(text, parse_constant=lambda _: None)
    return out


def _cell(value: Any) -> str:
    """A CSV cell: a float as the shortest decimal that reads back as it; a non-finite one (NaN
    PostgreSQL keeps, where SQLite stores NULL) empty, as NULL, so every reader sees one 'not known'."""
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else ""
    return str(value)


def table(rows: list[dict[str, Any]], columns: tuple[str, ...]) -> str:
    """Rows as aligned text columns, one line per row (numbers with 4 significant digits; a text
    that spans lines, such as a refusal message, joined with ' | ' as coefficients.csv has it)."""
    cells = [list(columns)] + [[_short(r.get(c)) for c in columns] for r in rows]
    widths = [max(len(line[i]) for line in cells) for i in range(len(columns))]
    return "\n".join("  ".join(v.ljust(w) for v, w in zip(line, widths)).rstrip() for line in cells)


def units_note(columns: tuple[str, ...]) -> str:
    """The units of the `list` table's columns that have one, as stored (SI; the table's header
    names the columns as --where and --columns take them): 'units: Kxx, Kxx_U N/m; Cxx N s/m'; ""
    when no column shown has a unit its name does not state (spin_rpm)."""
    by_unit: dict[str, list[str]] = {}
    for c in columns:
        unit = COLUMN_UNITS.get(c)
        if unit and not c.endswith("_" + unit):
            by_unit.setdefault(unit, []).append(c)
    if not by_unit:
        return ""
    return "units: " + "; ".join(f"{', '.join(cs)} {u}" for u, cs in by_unit.items()) + " (SI, as stored)"


def _short(value: Any) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.4g}"
    return one_line(value) if isinstance(value, str) else str(value)
