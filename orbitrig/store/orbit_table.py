"""Orbit table CSV (docs/orbit-table.md): read into / write from an OrbitTable.

Header row required, column order free, extra columns ignored. Units at this edge:
spin_rpm (rpm), orbit_hz (Hz), phasors in m and N, optional gamma2_* in [0, 1], optional
n_records (whole number >= 1) and u_x, u_y (m), u_fx, u_fy (N) (>= 0, a set of four). Inside:
rad/s. Every problem raises TableError naming the file, the line (1-based, the header is
line 1) and the column. UTF-8 (a BOM is allowed); blank lines are skipped; cells are plain
decimal numbers; empty fields past the header's last column (a trailing comma) are ignored.
"""

from __future__ import annotations

import csv
import io
import math
import re
from pathlib import Path

import numpy as np

from orbitrig.config import RPM
from orbitrig.errors import TableError
from reduction.errors import ReductionError
from reduction.table import GAMMA2_COLUMNS, U_COLUMNS, OrbitTable

REQUIRED = ("spin_rpm", "orbit_hz", "x_re", "x_im", "y_re", "y_im", "fx_re", "fx_im", "fy_re", "fy_im")
GAMMA2 = tuple(f"gamma2_{c}" for c in GAMMA2_COLUMNS)
UNCERTAINTY = tuple(f"u_{c}" for c in U_COLUMNS)
RECORDS = "n_records"


# a decimal number as a CSV writer prints it (Python's float() also takes '1_000' and spaces)
_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?|[+-]?(nan|inf|infinity)", re.IGNORECASE | re.ASCII)


def _number(raw: str) -> float | None:
    """The value of one cell, or None when it is not a plain decimal number."""
    return float(raw) if _NUMBER.fullmatch(raw) else None


class _Reader:
    """csv.reader whose format errors (e.g. an over-long field) become TableError with the line."""

    def __init__(self, file: str, reader):
        self.file, self.reader = file, reader

    @property
    def line_num(self) -> int:
        return self.reader.line_num

    def __iter__(self):
        return self

    def __next__(self) -> list[str]:
        try:
            return next(self.reader)
        except csv.Error as err:
            raise TableError(self.file, self.reader.line_num or 1, None, f"not a valid CSV row: {err}") from None


def read_orbit_table(path: str | Path) -> OrbitTable:
    """Read and validate an orbit table CSV; raises TableError(file, line, column, reason)."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as err:
        raise TableError(str(path), None, None, f"cannot read the file: {err}") from err
    return parse_orbit_table(data, path)


def parse_orbit_table(data: bytes, path: str | Path = "<table>") -> OrbitTable:
    """An orbit table from the CSV's bytes (``path`` names it in errors); as read_orbit_table."""
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        start = data.rfind(b"\n", 0, err.start) + 1
        line = data[: err.start].count(b"\n") + 1
        field = data[start: err.start].count(b",") + 1
        raise TableError(str(path), line, f"field {field}",
                         f"not UTF-8 text: byte 0x{data[err.start]:02x} ({err.reason}); "
                         "save the table as UTF-8 CSV") from None
    reader = _Reader(str(path), csv.reader(io.StringIO(text, newline="")))
    header, header_line = None, None
    for fields in reader:
        if any(f.strip() for f in fields):
            header, header_line = [f.strip() for f in fields], reader.line_num
            break
    if header is None:
        raise TableError(str(path), 1, None, "empty file: a header row is required")
    header = [_column_name(str(path), header_line, name) for name in header]
    wanted = _wanted_columns(str(path), header, header_line)
    index = {name: header.index(name) for name in wanted}
    rows = []
    for fields in reader:
        if not any(f.strip() for f in fields):
            continue
        line = reader.line_num
        if len(fields) > len(header) and any(f.strip() for f in fields[len(header):]):
            raise TableError(str(path), line, f"#{len(header) + 1} (no header)",
                             f"{len(fields)} fields but the header has {len(header)} columns")
        row = {name: _cell(str(path), line, name, fields, index[name], len(header)) for name in wanted}
        _check_row(str(path), line, row, rows[0] if rows else None)
        rows.append(row)
    if not rows:
        raise TableError(str(path), header_line + 1, None, "no data rows after the header")
    col = {name: np.array([r[name] for r in rows]) for name in wanted}
    gamma2 = np.stack([col[g] for g in GAMMA2], axis=1) if GAMMA2[0] in col else None
    u = np.stack([col[c] for c in UNCERTAINTY], axis=1) if UNCERTAINTY[0] in col else None
    try:
        return OrbitTable(
            spin=float(col["spin_rpm"][0]) * RPM,
            orbit=2 * math.pi * col["orbit_hz"],
            x=col["x_re"] + 1j * col["x_im"], y=col["y_re"] + 1j * col["y_im"],
            fx=col["fx_re"] + 1j * col["fx_im"], fy=col["fy_re"] + 1j * col["fy_im"],
            gamma2=gamma2, n_records=col.get(RECORDS), u=u)
    except ReductionError as err:  # defensive: every check above should have caught it
        raise TableError(str(path), None, None, str(err)) from err


#: the unit a column may state in its header ("orbit_hz [Hz]"); the table's units are fixed
COLUMN_UNITS = {"spin_rpm": "rpm", "orbit_hz": "Hz", **{f"{q}_{p}": u for q, u in (("x", "m"), ("y", "m"), ("fx", "N"),
                ("fy", "N")) for p in ("re", "im")}, **dict.fromkeys(GAMMA2, "1"), RECORDS: "1", "direction": "1",
                **dict(zip(UNCERTAINTY, ("m", "m", "N", "N")))}  # fmt: skip
_WITH_UNIT = re.compile(r"^(?P<name>\S+)\s*\[(?P<unit>[^\]]*)\]$")


def _column_name(file: str, line: int, field: str) -> str:
    """A header field's column name; a stated unit ("orbit_hz [Hz]") must be the column's."""
    match = _WITH_UNIT.match(field)
    if not match:
        return field
    name, unit = match["name"], match["unit"].strip()
    if name in COLUMN_UNITS and unit != COLUMN_UNITS[name]:
        raise TableError(file, line, field, f"the unit of {name} is {COLUMN_UNITS[name]}, not {unit!r}")
    return name


def _wanted_columns(file: str, header: list[str], header_line: int) -> tuple[str, ...]:
    """The columns to read: the required ones and the optional sets present."""
    seen = set()
    known = REQUIRED + GAMMA2 + UNCERTAINTY + (RECORDS,)
    for name in header:
        if name in seen and name in known:  # a repeated extra column is ignored like any other
            raise TableError(file, header_line, name, "column appears twice in the header")
        seen.add(name)
    for name in REQUIRED:
        if name not in seen:
            raise TableError(file, header_line, name, "required column missing from the header")
    wanted = REQUIRED
    for group, what in ((GAMMA2, "coherence"), (UNCERTAINTY, "uncertainty")):
        present = [g for g in group if g in seen]
        if present and len(present) != len(group):
            missing = next(g for g in group if g not in seen)
            raise TableError(file, header_line, missing,
                             f"{what} columns come as a set of four: {', '.join(group)}")
        wanted += group if present else ()
    return wanted + ((RECORDS,) if RECORDS in seen else ())


def _cell(file: str, line: int, name: str, fields: list[str], j: int, n_header: int) -> float:
    if j >= len(fields):
        raise TableError(file, line, name, f"missing value ({len(fields)} fields, header has {n_header})")
    raw = fields[j].strip()
    v = _number(raw)
    if v is None:
        raise TableError(file, line, name, f"not a number: {raw!r}")
    if not math.isfinite(v):
        raise TableError(file, line, name, f"not a finite number: {raw!r}")
    return v


def _check_row(file: str, line: int, row: dict, first: dict | None) -> None:
    if row["orbit_hz"] <= 0:
        raise TableError(file, line, "orbit_hz", f"orbit frequency must be > 0 Hz, got {row['orbit_hz']:g}")
    if row["spin_rpm"] < 0:
        raise TableError(file, line, "spin_rpm", f"spin speed must be >= 0 rpm, got {row['spin_rpm']:g}")
    if first is not None and row["spin_rpm"] != first["spin_rpm"]:
        raise TableError(file, line, "spin_rpm",
                         f"spin speed {row['spin_rpm']:g} rpm differs from the first row's "
                         f"{first['spin_rpm']:g} rpm (one operating point per table)")
    for g in GAMMA2:
        if g in row and not 0.0 <= row[g] <= 1.0:
            raise TableError(file, line, g, f"coherence must lie in [0, 1], got {row[g]:g}")
    for c in UNCERTAINTY:
        if c in row and row[c] < 0:
            raise TableError(file, line, c, f"uncertainty must be >= 0, got {row[c]:g}")
    if RECORDS in row and not (row[RECORDS] >= 1 and row[RECORDS] == round(row[RECORDS])):
        raise TableError(file, line, RECORDS, f"number of records must be a whole number >= 1, got {row[RECORDS]:g}")


def whirl_direction(x, y) -> np.ndarray:
    """+1 where the phasors x, y whirl forward (Im(conj(x) y) < 0; a circle: y = -i x), else -1."""
    return np.where(np.imag(np.conj(np.asarray(x)) * np.asarray(y)) < 0, 1, -1)


def orbit_table_columns(table: OrbitTable, direction: bool = False) -> dict[str, tuple[np.ndarray, str]]:
    """The orbit-table columns of ``table`` in order: name -> (values, unit), the optional
    ones (gamma2_*, n_records, u_*) only when the table has them, then with ``direction``
    that column (+1 forward, -1 backward whirl, from the phasors). Units as in the CSV."""
    cols = {"spin_rpm": (np.full(table.n, table.spin / RPM), "rpm"), "orbit_hz": (table.orbit / (2 * math.pi), "Hz")}
    for (name, z), unit in zip(table.phasors.items(), ("m", "m", "N", "N")):
        cols[f"{name}_re"], cols[f"{name}_im"] = (z.real, unit), (z.imag, unit)
    if table.gamma2 is not None:
        cols.update({g: (np.asarray(table.gamma2)[:, j], "1") for j, g in enumerate(GAMMA2)})
    if table.n_records is not None:
        cols[RECORDS] = (np.asarray(table.n_records, dtype=np.int64), "1")
    if table.u is not None:
        cols.update({c: (np.asarray(table.u)[:, j], unit) for j, (c, unit) in enumerate(zip(UNCERTAINTY, "mmNN"))})
    if direction:
        cols["direction"] = (whirl_direction(table.x, table.y), "1")
    return cols


def write_orbit_table(path: str | Path, table: OrbitTable, units: bool = False) -> None:
    """Write ``table`` as an orbit table CSV (full float precision; gamma2, n_records and u_*
    when present), durably (orbitrig.store.durable.write_atomic; a StorageError names the file).
    ``units``: each header field states its unit (``orbit_hz [Hz]``) and a ``direction``
    column follows (+1 forward, -1 backward whirl; readers ignore it)."""
    from orbitrig.store.durable import write_atomic

    cols = orbit_table_columns(table, direction=units)
    fh = io.StringIO(newline="")
    w = csv.writer(fh, lineterminator="\r\n")
    w.writerow([f"{name} [{unit}]" if units else name for name, (_, unit) in cols.items()])
    for k in range(table.n):
        w.writerow([str(int(v[k])) if name in (RECORDS, "direction") else repr(float(v[k]))
                    for name, (v, _) in cols.items()])
    write_atomic(Path(path), fh.getvalue().encode("utf-8"))
