"""The orbit table CSV read row by row, in blocks of ``BLOCK_ROWS`` rows: each block converted
column by column when every cell is a plain finite decimal and every value in range, else row by
row to raise the first fault as TableError(file, line, column, reason). Units as in the CSV
(spin_rpm in rpm, orbit_hz in Hz, phasors in m and N).
"""

from __future__ import annotations

import csv
import math
import re

import numpy as np

from orbitrig.errors import IgnoredColumnWarning, TableError
from orbitrig.store.orbit_table_header import GAMMA2, RECORDS, UNCERTAINTY, column_name, wanted_columns

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


def read_columns(file: str, fh) -> tuple[dict[str, np.ndarray], list[IgnoredColumnWarning]]:
    """The wanted columns of a CSV stream, validated, as float arrays; the header's near-miss warnings."""
    reader = _Reader(file, csv.reader(fh))
    for fields in reader:
        if any(f.strip() for f in fields):
            header, header_line = [f.strip() for f in fields], reader.line_num
            break
    else:
        raise TableError(file, 1, None, "empty file: a header row is required")
    header = [column_name(file, header_line, name) for name in header]
    wanted, ignored = wanted_columns(file, header, header_line)
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
    if fast and in_range(col, first or {name: col[name][0] for name in wanted}):
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


def in_range(col: dict[str, np.ndarray], first: dict[str, float]) -> bool:
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
