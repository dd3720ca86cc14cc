"""The orbit table CSV's header (docs/orbit-table.md): the known columns, the unit each may
state ("orbit_hz [Hz]"; "[1]" or "[-]" dimensionless), the columns read (the required ones and
the optional sets of four present, n_records), and the extra columns that look like a misspelt
known one (each named in an IgnoredColumnWarning, and in the error of the column it leaves missing).
"""

from __future__ import annotations

import difflib
import re

from orbitrig.errors import IgnoredColumnWarning, TableError
from reduction.columns import GAMMA2_COLUMNS, U_COLUMNS

REQUIRED = ("spin_rpm", "orbit_hz", "x_re", "x_im", "y_re", "y_im", "fx_re", "fx_im", "fy_re", "fy_im")
GAMMA2 = tuple(f"gamma2_{c}" for c in GAMMA2_COLUMNS)
UNCERTAINTY = tuple(f"u_{c}" for c in U_COLUMNS)
RECORDS = "n_records"
KNOWN = REQUIRED + GAMMA2 + UNCERTAINTY + (RECORDS,)


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


def column_name(file: str, line: int, field: str) -> str:
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


def wanted_columns(
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
