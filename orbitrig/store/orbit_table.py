"""Orbit table CSV (docs/orbit-table.md): read into / write from an OrbitTable.

Header row required, column order free, extra columns ignored. Units at this edge:
spin_rpm (rpm), orbit_hz (Hz), phasors in m and N, optional gamma2_* in [0, 1], optional
n_records (whole number >= 1) and u_x, u_y (m), u_fx, u_fy (N) (>= 0, a set of four). Inside:
rad/s. Every problem raises TableError naming the file, the line (1-based, the header is
line 1) and the column. UTF-8 (a BOM is allowed); blank lines are skipped; cells are plain
decimal numbers; empty fields past the header's last column (a trailing comma) are ignored.
A header field may state its unit ("orbit_hz [Hz]"; "[1]" or "[-]" dimensionless). An extra
column that looks like a misspelt known one (``u_fX``) is named in an IgnoredColumnWarning; the
error of a required column or set of four it leaves missing names it as the likely cause.
"""

from __future__ import annotations

import csv
import difflib
import io
import math
import re
import warnings
from pathlib import Path

import numpy as np

from orbitrig.config import RPM
from orbitrig.errors import IgnoredColumnWarning, TableError
from reduction.errors import ReductionError
from reduction.table import GAMMA2_COLUMNS, U_COLUMNS, OrbitTable

REQUIRED = ("spin_rpm", "orbit_hz", "x_re", "x_im", "y_re", "y_im", "fx_re", "fx_im", "fy_re", "fy_im")
GAMMA2 = tuple(f"gamma2_{c}" for c in GAMMA2_COLUMNS)
UNCERTAINTY = tuple(f"u_{c}" for c in U_COLUMNS)
RECORDS = "n_records"
KNOWN = REQUIRED + GAMMA2 + UNCERTAINTY + (RECORDS,)


# a decimal number as a CSV writer prints it (Python's float() also takes '1_000' and spaces)
BLOCK_ROWS = 50000  # rows converted at once
_DECIMAL_CHARS = frozenset("0123456789+-.eE \t")  # a cell float() reads from these alone is a plain decimal
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
    """Read and validate an orbit table CSV; raises TableError(file, line, column, reason).
    The file is streamed in blocks of ``BLOCK_ROWS`` rows, each converted column by column
    (a block with any fault is read again row by row to name the line and column)."""
    path = Path(path)
    try:
        col = _columns(str(path), lambda: open(path, encoding="utf-8-sig", newline=""))
    except UnicodeDecodeError:
        raise _not_utf8(path.read_bytes(), str(path)) from None
    except OSError as err:
        raise TableError(str(path), None, None, f"cannot read the file: {err}") from err
    return _table(str(path), col)


def parse_orbit_table(data: bytes, path: str | Path = "<table>") -> OrbitTable:
    """An orbit table from the CSV's bytes (``path`` names it in errors); as read_orbit_table."""
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise _not_utf8(data, str(path)) from None
    return _table(str(path), _columns(str(path), lambda: io.StringIO(text, newline="")))


def _columns(file: str, open_text) -> dict[str, np.ndarray]:
    """The validated columns of the text ``open_text()`` opens: numpy's C reader first, the
    row-by-row reader when anything is amiss (it names the line and column). A header column
    that looks like a misspelt known one is warned of (IgnoredColumnWarning) once the table is read."""
    with open_text() as fh:
        read = _load_columns(file, fh)
    if read is None:
        with open_text() as fh:
            read = _read_columns(file, fh)
    col, ignored = read
    for warning in ignored:  # here, outside the numeric readers' warning filters
        warnings.warn(warning, stacklevel=3)
    return col


def _table(file: str, col: dict[str, np.ndarray]) -> OrbitTable:
    gamma2 = np.stack([col[g] for g in GAMMA2], axis=1) if GAMMA2[0] in col else None
    u = np.stack([col[c] for c in UNCERTAINTY], axis=1) if UNCERTAINTY[0] in col else None
    try:
        return OrbitTable(
            spin=float(col["spin_rpm"][0]) * RPM,
            orbit=2 * math.pi * col["orbit_hz"],
            x=col["x_re"] + 1j * col["x_im"],
            y=col["y_re"] + 1j * col["y_im"],
            fx=col["fx_re"] + 1j * col["fx_im"],
            fy=col["fy_re"] + 1j * col["fy_im"],
            gamma2=gamma2,
            n_records=col.get(RECORDS),
            u=u,
        )
    except ReductionError as err:  # defensive: every check above should have caught it
        raise TableError(file, None, None, str(err)) from err


def _not_utf8(data: bytes, file: str) -> TableError:
    try:
        data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        start = data.rfind(b"\n", 0, err.start) + 1
        line = data[: err.start].count(b"\n") + 1
        field = data[start : err.start].count(b",") + 1
        return TableError(
            file,
            line,
            f"field {field}",
            f"not UTF-8 text: byte 0x{data[err.start]:02x} ({err.reason}); save the table as UTF-8 CSV",
        )
    return TableError(file, None, None, "not UTF-8 text; save the table as UTF-8 CSV")


def _load_columns(file: str, fh) -> tuple[dict[str, np.ndarray], list[IgnoredColumnWarning]] | None:
    """The wanted columns by numpy's C reader, or None when anything is amiss (a cell that
    is not a finite decimal number, a value out of range, a ragged row): the row-by-row
    reader then names the line and column; so does a table with a column that is not
    numbers (an ignored extra column). The header is checked (its near misses listed) here."""
    for line_no, text in enumerate(fh, start=1):
        if text.strip():
            header = [_column_name(file, line_no, f.strip()) for f in next(csv.reader([text]))]
            break
    else:
        return None
    wanted, ignored = _wanted_columns(file, header, line_no)
    try:  # every column, so that a row with more fields than the header is not passed over
        data = _parse_numbers(fh)
    except ValueError:
        return None
    if (
        data is None
        or len(data) != len(header)
        or data[0].shape[0] == 0
        or not all(np.all(np.isfinite(c)) for c in data)
    ):
        return None
    col = {name: data[header.index(name)] for name in wanted}
    return (col, ignored) if _in_range(col, {name: col[name][0] for name in wanted}) else None


def _parse_numbers(fh) -> list[np.ndarray] | None:
    """Every column of the rest of ``fh`` as float arrays, by pandas' C parser when pandas
    is installed (about 2.5 times faster than numpy's on a long table; both read every
    decimal to the nearest double), else numpy's; ValueError on a cell that is not a number
    or a ragged row (NaN for a missing cell)."""
    try:
        import pandas as pd
    except ImportError:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # "no data": the row-by-row reader says so
            data = np.loadtxt(fh, delimiter=",", comments=None, ndmin=2, quotechar='"')
        return list(data.T)
    try:
        frame = pd.read_csv(fh, header=None, dtype=float, quotechar='"', skip_blank_lines=True)
    except pd.errors.EmptyDataError:
        return None
    return [frame[c].to_numpy() for c in frame.columns]


def _read_columns(file: str, fh) -> tuple[dict[str, np.ndarray], list[IgnoredColumnWarning]]:
    """The wanted columns of a CSV stream, validated, as float arrays; the header's near-miss warnings."""
    reader = _Reader(file, csv.reader(fh))
    for fields in reader:
        if any(f.strip() for f in fields):
            header, header_line = [f.strip() for f in fields], reader.line_num
            break
    else:
        raise TableError(file, 1, None, "empty file: a header row is required")
    header = [_column_name(file, header_line, name) for name in header]
    wanted, ignored = _wanted_columns(file, header, header_line)
    index = {name: header.index(name) for name in wanted}
    blocks, block, lines, first = [], [], [], None
    for fields in reader:
        if not any(f.strip() for f in fields):
            continue
        block.append(fields)
        lines.append(reader.line_num)
        if len(block) == BLOCK_ROWS:
            blocks.append(_block(file, block, lines, wanted, index, len(header), first))
            first = first or {name: blocks[0][name][0] for name in wanted}
            block, lines = [], []
    if block:
        blocks.append(_block(file, block, lines, wanted, index, len(header), first))
    if not blocks:
        raise TableError(file, header_line + 1, None, "no data rows after the header")
    return {name: np.concatenate([b[name] for b in blocks]) for name in wanted}, ignored


def _block(file, rows, lines, wanted, index, n_header, first) -> dict[str, np.ndarray]:
    """One block of rows as columns: converted at once when every cell is a plain finite
    number and every value in range, else row by row to raise the first fault."""
    fast = all(len(f) == n_header for f in rows)
    col = {}
    for name in wanted if fast else ():
        cells = [f[index[name]] for f in rows]
        try:
            if set("".join(cells)) - _DECIMAL_CHARS:
                raise ValueError
            col[name] = np.fromiter(map(float, cells), float, len(cells))
        except ValueError:
            fast = False
            break
    if fast and _in_range(col, first or {name: col[name][0] for name in wanted}):
        return col
    out: list[dict[str, float]] = []
    for line, fields in zip(lines, rows):
        if len(fields) > n_header and any(f.strip() for f in fields[n_header:]):
            raise TableError(
                file,
                line,
                f"#{n_header + 1} (no header)",
                f"{len(fields)} fields but the header has {n_header} columns",
            )
        row = {name: _cell(file, line, name, fields, index[name], n_header) for name in wanted}
        _check_row(file, line, row, first or (out[0] if out else None))
        out.append(row)
    return {name: np.array([r[name] for r in out]) for name in wanted}


def _in_range(col: dict[str, np.ndarray], first: dict[str, float]) -> bool:
    """Every value of the block within the checks of ``_check_row``."""
    ok = bool(
        np.all(col["orbit_hz"] > 0) and np.all(col["spin_rpm"] >= 0) and np.all(col["spin_rpm"] == first["spin_rpm"])
    )
    for g in GAMMA2:
        ok = ok and (g not in col or bool(np.all((col[g] >= 0) & (col[g] <= 1))))
    for c in UNCERTAINTY:
        ok = ok and (c not in col or bool(np.all(col[c] >= 0)))
    if RECORDS in col:
        r = col[RECORDS]
        ok = ok and bool(np.all((r >= 1) & (r == np.round(r))))
    return ok


#: the unit a column may state in its header ("orbit_hz [Hz]"); the table's units are fixed
COLUMN_UNITS = {
    "spin_rpm": "rpm",
    "orbit_hz": "Hz",
    **{f"{q}_{p}": u for q, u in (("x", "m"), ("y", "m"), ("fx", "N"), ("fy", "N")) for p in ("re", "im")},
    **dict.fromkeys(GAMMA2, "1"),
    RECORDS: "1",
    "direction": "1",
    **dict(zip(UNCERTAINTY, ("m", "m", "N", "N"))),
}
_WITH_UNIT = re.compile(r"^(?P<name>\S+)\s*\[(?P<unit>[^\]]*)\]$")
DIMENSIONLESS = ("1", "-")  # how a dimensionless column may state its unit (the shared contract writes "-")


def _column_name(file: str, line: int, field: str) -> str:
    """A header field's column name; a stated unit ("orbit_hz [Hz]") must be the column's
    ("gamma2_xfx [1]" or "gamma2_xfx [-]" for a dimensionless one)."""
    match = _WITH_UNIT.match(field)
    if not match:
        return field
    name, unit = match["name"], match["unit"].strip()
    known = DIMENSIONLESS if COLUMN_UNITS.get(name) == "1" else (COLUMN_UNITS.get(name, unit),)
    if unit not in known:
        raise TableError(file, line, field, f"the unit of {name} is {' or '.join(map(repr, known))}, not {unit!r}")
    return name


def _wanted_columns(
    file: str, header: list[str], header_line: int
) -> tuple[tuple[str, ...], list[IgnoredColumnWarning]]:
    """The columns to read: the required ones and the optional sets present; and a warning for each
    extra column that looks like a misspelt known one (not read: a missing column's error names it)."""
    seen = set()
    for name in header:
        if name in seen and name in KNOWN:  # a repeated extra column is ignored like any other
            raise TableError(file, header_line, name, "column appears twice in the header")
        seen.add(name)
    misses = _near_misses(header)
    hint = {
        k: f" (column '{n}' in the header looks like it): likely misspelt, so not read; rename it {k}"
        for n, k in reversed(misses.items())
    }
    for name in REQUIRED:
        if name not in seen:
            raise TableError(file, header_line, name, "required column missing from the header" + hint.get(name, ""))
    wanted: tuple[str, ...] = REQUIRED
    for group, what in ((GAMMA2, "coherence"), (UNCERTAINTY, "uncertainty")):
        present = [g for g in group if g in seen]
        if present and len(present) != len(group):
            missing = next(g for g in group if g not in seen)
            reason = f"{what} columns come as a set of four: {', '.join(group)}{hint.get(missing, '')}"
            raise TableError(file, header_line, missing, reason)
        wanted += group if present else ()
    ignored = [IgnoredColumnWarning(file, header_line, name, known) for name, known in misses.items()]
    return wanted + ((RECORDS,) if RECORDS in seen else ()), ignored


def _near_misses(header: list[str]) -> dict[str, str]:
    """Header column -> the absent known column it looks like a misspelling of: equal but for case, '_'
    and ' ' (``U_fx``, ``nrecords``), or close (``n_record``, ``gamma_xfx``); not ``comment``, ``direction``."""
    absent = [k for k in KNOWN if k not in header]
    squashed = {k.replace("_", ""): k for k in KNOWN}
    misses = {}
    for name in header:
        key = name.lower().replace("_", "").replace(" ", "")
        if name in COLUMN_UNITS or not key:  # a known column, or ``direction``
            continue
        like = [squashed[key]] if key in squashed else difflib.get_close_matches(name.lower(), absent, 1, 0.8)
        if like and like[0] in absent:  # a known column present is not suggested again
            misses[name] = like[0]
    return misses


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
        why = f"spin speed {row['spin_rpm']:g} rpm differs from the first row's {first['spin_rpm']:g} rpm"
        raise TableError(file, line, "spin_rpm", f"{why} (one operating point per table)")
    for g in GAMMA2:
        if g in row and not 0.0 <= row[g] <= 1.0:
            raise TableError(file, line, g, f"coherence must lie in [0, 1], got {row[g]:g}")
    for c in UNCERTAINTY:
        if c in row and row[c] < 0:
            raise TableError(file, line, c, f"uncertainty must be >= 0, got {row[c]:g}")
    if RECORDS in row and not (row[RECORDS] >= 1 and row[RECORDS] == round(row[RECORDS])):
        raise TableError(file, line, RECORDS, f"number of records must be a whole number >= 1, got {row[RECORDS]:g}")


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
        cols["direction"] = (np.where(table.forward(), 1, -1), "1")
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
        w.writerow(
            [str(int(v[k])) if name in (RECORDS, "direction") else repr(float(v[k])) for name, (v, _) in cols.items()]
        )
    write_atomic(Path(path), fh.getvalue().encode("utf-8"))
