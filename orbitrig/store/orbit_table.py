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
import io
import warnings
from pathlib import Path

import numpy as np

from orbitrig.config import RPM
from orbitrig.errors import IgnoredColumnWarning, TableError
from orbitrig.store.orbit_table_header import GAMMA2, RECORDS, UNCERTAINTY, column_name, wanted_columns
from orbitrig.store.orbit_table_rows import in_range, read_columns
from reduction.errors import ReductionError
from reduction.table import OrbitTable
from rigunits import HZ, in_rpm


def read_orbit_table(path: str | Path) -> OrbitTable:
    """Read and validate an orbit table CSV; raises TableError(file, line, column, reason).
    The file is streamed in blocks of ``orbit_table_rows.BLOCK_ROWS`` rows, each converted column by column
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
            read = read_columns(file, fh)
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
            orbit=HZ * col["orbit_hz"],
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
            header = [column_name(file, line_no, f.strip()) for f in next(csv.reader([text]))]
            break
    else:
        return None
    wanted, ignored = wanted_columns(file, header, line_no)
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
    return (col, ignored) if in_range(col, {name: col[name][0] for name in wanted}) else None


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


def orbit_table_columns(table: OrbitTable, direction: bool = False) -> dict[str, tuple[np.ndarray, str]]:
    """The orbit-table columns of ``table`` in order: name -> (values, unit), the optional
    ones (gamma2_*, n_records, u_*) only when the table has them, then with ``direction``
    that column (+1 forward, -1 backward whirl, from the phasors). Units as in the CSV."""
    cols = {"spin_rpm": (np.full(table.n, in_rpm(table.spin)), "rpm"), "orbit_hz": (table.orbit_hz, "Hz")}
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
    from orbitrig.store.csvfile import render_rows
    from orbitrig.store.durable import write_atomic

    cols = orbit_table_columns(table, direction=units)
    header = [f"{name} [{unit}]" if units else name for name, (_, unit) in cols.items()]
    rows = (
        [str(int(v[k])) if name in (RECORDS, "direction") else repr(float(v[k])) for name, (v, _) in cols.items()]
        for k in range(table.n)
    )
    write_atomic(Path(path), render_rows([header, *rows], line_end="\r\n"))
