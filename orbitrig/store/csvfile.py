"""coefficients.csv: one row per (operating point, load measuring system, model).

Every column name states its unit (``spin_rpm``, ``recess_pressure_mpa``, ``Kxx [N/m]``,
``Cxy_1 [N s/m (rad/s)^-1]``, ``residual_rms [N]``); every row is one physical line
(a refusal message that spans lines is joined with ' | ', and so are a fit's ``warnings``,
its reasons to distrust it: ill-conditioning, a bad chi2, weak excitation, bias). Numbers are SI except the
settings columns, whose names give their unit. Empty cell: no value (refused model,
or a number the identification could not give). ``{name}_U`` is the expanded uncertainty
(statistical and calibration combined; statistical only when the rig states no calibration
uncertainty), ``{name}_k`` its coverage factor (orbitrig.store.fit_record.expanded_ks: Student's
t at 95.45 % at the effective dof, 2 where every part is known exactly); ``not_determined`` lists (space-separated) the coefficients whose
U exceeds their magnitude. The ``true_*`` columns of a --sim run are the fit's own truth:
the simulator's true Z(Omega) projected onto the fit's model (orbitrig.run.model_truth);
runs stored before that show the constant K, C, D best fit (the truth's K0, C0, D0).
"""

from __future__ import annotations

import csv
import io
import sys
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from orbitrig.store.fit_record import expanded_ks, expanded_uncertainty
from orbitrig.store.layout import PRESSURE_DISPLAY_UNIT, SETTINGS_UNITS
from rigunits import MPA, coefficient_unit

if TYPE_CHECKING:
    from orbitrig.store.stored_run import Point

#: one row of coefficients.csv: column name -> cell
CsvRow = dict[str, Any]

CSV_HEAD = [
    "point",
    "label",
    "spin_rpm",
    "recess_pressure_mpa",
    "pressure_ratio",
    "static_eccentricity",
    "dynamic_eccentricity",
    "lms",
    "model",
    "freq_dep",
    "method",
    "n_frequencies",
    "condition_number",
    "residual_rms [N]",
    "error",
    "not_determined",
    "warnings",
]
#: the head columns holding text (the others hold numbers)
TEXT_COLUMNS = ("label", "lms", "model", "freq_dep", "method", "error", "not_determined", "warnings")
#: the unit of each numeric head column that does not state it in brackets, as pint parses it
HEAD_UNITS = {
    "point": "1",
    "spin_rpm": SETTINGS_UNITS["spin_rpm"],
    "recess_pressure_mpa": PRESSURE_DISPLAY_UNIT,
    **{
        k: SETTINGS_UNITS[k] for k in ("pressure_ratio", "static_eccentricity", "dynamic_eccentricity", "n_frequencies")
    },
    "condition_number": "1",
}


def column_unit(column: str) -> str:
    """The unit of a coefficients.csv column as pint parses it ('Kxx [N/m]' -> 'N/m',
    'spin_rpm' -> 'rpm', 'pressure_ratio' -> '1'); "" for a text column."""
    if column.endswith("]") and " [" in column:
        return column[column.index(" [") + 2 : -1]
    return HEAD_UNITS.get(column, "")


def coefficient_column(key: str, kind: str = "") -> str:
    """Column name of coefficient `key`: kind '' -> 'Kxx [N/m]', 'std' -> 'Kxx_std [N/m]',
    'U' -> 'Kxx_U [N/m]', 'k' -> 'Kxx_k [1]' (U's coverage factor), 'true' -> 'true_Kxx [N/m]'."""
    unit = coefficient_unit(key)
    if kind == "k":
        return f"{key}_k [1]"
    if kind in ("std", "U"):
        return f"{key}_{kind} [{unit}]"
    return f"{'true_' if kind == 'true' else ''}{key} [{unit}]"


def coef_order(key: str) -> tuple[int, int, str, str]:
    """Kxx, Kxy, Kyx, Kyy, Cxx, ..., Dyy, then the Omega^r terms (Kxx_1, ...)."""
    base, _, r = key.partition("_")
    return (int(r) if r.isdigit() else 0, "KCD".find(base[:1]), base[1:], key)


def one_line(text: str) -> str:
    """A message as one CSV line: line breaks become ' | '."""
    return " | ".join(part.strip() for part in str(text).splitlines() if part.strip())


def warnings_cell(warnings: Iterable[str] | None) -> str:
    """A fit's ``warnings`` (reasons to distrust it) as one CSV cell: each as one line
    (`one_line`), joined with ' | '; "" for none."""
    return " | ".join(filter(None, (one_line(w) for w in warnings or ())))


def true_entry(truth: dict[str, Any], key: str) -> float:
    """True constant-term value of coefficient `key` ('Kxy' ...) at the lowest |Omega|."""
    mat = truth[key[0] + "0"]
    return float(mat["xy".index(key[1])]["xy".index(key[2])])


def fit_truth(d: dict[str, Any] | None, truth: dict[str, Any] | None) -> dict[str, float]:
    """The true value of every coefficient of a stored fit ``d``: its own truth (the true Z
    projected onto its model) when stored, else the point's constant best fit (constant
    terms only); {} without a truth."""
    own = ((d or {}).get("truth") or {}).get("coefficients")
    if own is not None:
        return {k: v for k, v in own.items() if v is not None}
    if not truth or d is None:
        return {}
    return {k: true_entry(truth, k) for k in d["coefficients"] if "_" not in k and f"{k[0]}0" in truth}


def fit_cells(d: dict[str, Any]) -> dict[str, Any]:
    """The cells of a stored fit ``d`` (its identify JSON) that judge it as a whole, as
    coefficients.csv and the API's ``run.coefficients`` show them: ``n_frequencies`` (rows of
    its orbit table), ``not_determined`` (space-separated keys whose U exceeds their magnitude)
    and ``warnings`` (`warnings_cell`)."""
    return {
        "n_frequencies": d["n_frequencies"],
        "not_determined": " ".join(d.get("not_determined") or []),
        "warnings": warnings_cell(d.get("warnings")),
    }


def _num(v: float | None, fmt: str) -> str:
    """A CSV cell: the number in `fmt`, empty for null (the identify JSON's non-finite values);
    fmt "" gives the shortest text that reads back as the same double."""
    return "" if v is None else format(float(v), fmt)


def point_rows(point: Point, sim: bool, exact: bool = False) -> list[CsvRow]:
    """The rows of one complete point (an orbitrig.store.stored_run.Point), numbers rounded for
    reading at a glance (coefficients and true values 8 significant digits, the rest 6), or
    with `exact` every number to the last bit (the TDMS export's ``coefficients`` group, which
    holds them as doubles beside the fits' own channels)."""
    st = point.settings
    six, eight = ("", "") if exact else (".6g", ".8g")
    base = {
        "point": point.index,
        "label": st.label,
        "spin_rpm": _num(st.spin_rpm, six),
        "recess_pressure_mpa": _num(st.recess_pressure / MPA, six),
        "pressure_ratio": _num(st.pressure_ratio, six),
        "static_eccentricity": _num(st.static_eccentricity, six),
        "dynamic_eccentricity": _num(st.dynamic_eccentricity, six),
    }
    truth = point.truth if sim else None
    rows = []
    for ident in point.identifications:
        row = dict(base, lms=ident.lms, model=ident.model, _keys=[])
        d = ident.result
        if d is not None:
            row.update(
                {
                    "freq_dep": d["freq_dep"],
                    "method": d["method"],
                    "condition_number": _num(d["condition_number"], six),
                    "residual_rms [N]": _num(d["residual_rms"], six),
                    "error": "",
                }
            )
            expanded, ks = expanded_uncertainty(d), expanded_ks(d)
            for k, v in d["coefficients"].items():
                row[coefficient_column(k)] = _num(v, eight)
                row[coefficient_column(k, "std")] = _num((d.get("std_errors") or {}).get(k), six)
                row[coefficient_column(k, "U")] = _num(expanded.get(k), six)
                row[coefficient_column(k, "k")] = _num(ks.get(k), six)
            row["_keys"] = list(d["coefficients"])
            row.update(fit_cells(d))
        else:
            row.update(freq_dep=ident.freq_dep, method=ident.method, error=one_line(ident.error or ""))
        if truth is not None:
            for k, v in fit_truth(d, truth).items():
                row[coefficient_column(k, "true")] = _num(v, eight)
        rows.append(row)
    return rows


def columns(rows: list[CsvRow]) -> list[str]:
    """The file's columns for `rows` as dicts (`_layout`)."""
    return _layout((k for r in rows for k in r["_keys"]), lambda c: any(c in r for r in rows))


def _layout(keys: Iterable[str], has: Callable[[str], bool]) -> list[str]:
    """CSV_HEAD, then each coefficient of `keys`, its standard error, expanded uncertainty and
    its k, then the true values of those whose true column some row `has`."""
    ordered = sorted(dict.fromkeys(keys), key=coef_order)
    cols = CSV_HEAD + [coefficient_column(k, kind) for k in ordered for kind in ("", "std", "U", "k")]
    return cols + [c for c in (coefficient_column(k, "true") for k in ordered) if has(c)]


def render(rows: list[CsvRow]) -> bytes:
    """The whole file's bytes (UTF-8, header + one line per row)."""
    return render_table(columns(rows), rows)


@dataclass(frozen=True)
class PointCsv:
    """One complete point's rows as a run keeps them between two writes of the file: its
    coefficient keys, its own columns and its rows as CSV text in those columns (about a
    tenth of the memory of the rows as dicts)."""

    keys: tuple[str, ...]
    fields: tuple[str, ...]
    body: str

    @classmethod
    def of(cls, rows: list[CsvRow]) -> PointCsv:
        fields = [sys.intern(c) for c in columns(rows)]
        buf = io.StringIO(newline="")
        csv.DictWriter(buf, fieldnames=fields, restval="", extrasaction="ignore", lineterminator="\n").writerows(rows)
        keys = dict.fromkeys(sys.intern(k) for r in rows for k in r["_keys"])
        return cls(tuple(keys), tuple(fields), buf.getvalue())


def render_points(points: list[PointCsv]) -> bytes:
    """The whole file's bytes from each point's kept rows; the same bytes as `render` of
    their rows as dicts."""
    have = {f for p in points for f in p.fields}
    cols = _layout((k for p in points for k in p.keys), have.__contains__)
    buf = io.StringIO(newline="")
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    for p in points:
        at = {f: i for i, f in enumerate(p.fields)}
        where = [at.get(c) for c in cols]
        for cells in csv.reader(io.StringIO(p.body, newline="")):
            w.writerow(["" if i is None else cells[i] for i in where])
    return buf.getvalue().encode("utf-8")


def render_rows(rows: Iterable[Sequence[object]], line_end: str = "\n") -> bytes:
    """A CSV's bytes from its rows as lists of cells (header included), one line per row: the
    writer of the exports' other CSV files (orbitrig.store.export_csv) and of orbit tables
    (orbitrig.store.orbit_table, ``line_end`` CR LF as they always had)."""
    buf = io.StringIO(newline="")
    csv.writer(buf, lineterminator=line_end).writerows(rows)
    return buf.getvalue().encode("utf-8")


def render_table(fieldnames: list[str], rows: list[CsvRow]) -> bytes:
    """A coefficients-layout CSV's bytes: the header `fieldnames`, one line per row (missing
    cells empty, keys not in `fieldnames` ignored). The one writer of coefficients.csv and of
    `orbitrig reduce`'s file; write the bytes with orbitrig.store.durable.write_atomic."""
    buf = io.StringIO(newline="")
    w = csv.DictWriter(buf, fieldnames=fieldnames, restval="", extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    return buf.getvalue().encode("utf-8")
