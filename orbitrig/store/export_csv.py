"""``orbitrig export --format csv``: CSV files, every header field with its unit.

- ``point_PPPP_<lms>.csv``: the orbit table (docs/orbit-table.md; ``orbit_hz [Hz]`` ...,
  ``direction [1]``), which `orbitrig identify` reads;
- ``coefficients.csv``: as the run's (one row per point, load measuring system and fit);
- ``fits.csv``: one row per point, fit and coefficient: ``value``, ``std``, ``U``, ``k [1]`` (its own k), the
  interval value -+ U ``interval_95_low``, ``interval_95_high`` with its ``interval_95_basis``
  (combined | statistical only), the fit's statistical-only 95 % interval
  ``interval_95_statistical_low``, ``interval_95_statistical_high``, the budget's parts in the row's
  ``unit``, ``e_n``, ``true`` (--sim: the fit's own truth), ``error`` and the fit's
  ``warnings`` (joined with ' | ', on each of its rows);
- ``covariance_PPPP_<key>.csv``: the covariance, the free coefficients' names as the first
  column and the header, each row's coefficient unit in the second column ``unit`` (entry in
  unit(row) x unit(column), as `identify --format csv` gives it);
- ``fit_properties.csv``: one row per point, fit and single value (``name``, ``value``,
  ``unit``; ``unit`` empty for text): ``dof``, ``chi2``, ``p_value``, ``aic``, ``bic`` (where
  the fit gives them), ``interval`` (normal | student_t), ``confidence_level`` (of the
  statistical interval), ``k`` (the largest coverage factor of U), ``interval_95_basis``, the adequacy test
  (``adequacy_verdict``, ``adequacy_test``, ``adequacy_dof_numerator`` ...) and what the
  derived quantities rest on (``derived_covariance``, ``derived_c_eff_zero_xx_omega_0`` ...);
- ``derived_PPPP_<key>.csv``: the derived quantities at the point's orbit frequencies;
- ``runout_turns_PPPP.csv``: per block, in the orbit table's row order, the spin turns per board
  revolution its runout is placed with (export_content.RUNOUT_TURNS: ``orbit_hz [Hz]``,
  ``direction [1]``, ``commanded [1]``, ``fitted [1]``, ``u [1]`` (empty: not fitted),
  ``resolved [1]`` (1 true), ``used [1]``, ``unfitted`` (text));
- ``provenance.csv``: software version, creation time, status, configuration, the simulator
  scenario's and the calibration record's TOML text (a multi-line value is one quoted cell).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from orbitrig.store import csvfile
from orbitrig.store import export_content as content
from orbitrig.store.durable import write_atomic
from orbitrig.store.fit_record import BUDGET_PARTS, point_fits
from orbitrig.store.orbit_table import write_orbit_table

if TYPE_CHECKING:
    from orbitrig.store.stored_run import Point, Run

#: a CSV row: numbers and text
Row = Sequence[object]

FIT_HEAD = [
    "point",
    "lms",
    "model",
    "freq_dep",
    "method",
    "name",
    "unit",
    "value",
    "std",
    "U",
    "k [1]",
    "interval_95_low",
    "interval_95_high",
    "interval_95_basis",
    "interval_95_statistical_low",
    "interval_95_statistical_high",
    *BUDGET_PARTS,
    "e_n [1]",
    "true",
    "error",
    "warnings",
]


def _cell(v: float | None) -> str:
    return "" if v is None or (isinstance(v, float) and math.isnan(v)) else repr(float(v))


def _fit_rows(p: Point, sim: bool) -> list[Row]:
    rows: list[Row] = []
    for fit in point_fits(p):
        d = content.fit_arrays(fit)
        head = [p.index, fit.lms, fit.model, fit.freq_dep, fit.method]
        warns = csvfile.warnings_cell(d["warnings"])
        if fit.error:
            rows.append(head + [""] * (len(FIT_HEAD) - 7) + [csvfile.one_line(fit.error), warns])
            continue
        for j, name in enumerate(fit.names):
            interval = [_cell(v) for v in d["interval_95"][j]] if "interval_95" in d else ["", ""]
            interval.append(str(d.get("interval_95_basis", "")))
            stat = d.get("interval_95_statistical")
            interval += [_cell(v) for v in stat[j]] if stat is not None else ["", ""]
            parts = [_cell(d[part][j]) if part in d else "" for part in BUDGET_PARTS]
            true = csvfile.fit_truth(fit.result, p.truth if sim else None).get(name)
            e_n = _cell(d["e_n"][j]) if "e_n" in d else ""
            k = _cell(d["expanded_k"][j]) if "expanded_k" in d else ""
            values = [_cell(d["value"][j]), _cell(d["std"][j]), _cell(d["U"][j]), k, *interval, *parts]
            rows.append(head + [name, fit.units[j], *values, e_n, _cell(true), "", warns])
    return rows


PROPERTY_HEAD = ["point", "lms", "model", "freq_dep", "method", "name", "value", "unit"]


def _property_rows(p: Point) -> list[Row]:
    """The fit_properties.csv rows of point `p`: each fit's FIT_QUALITY (dof, chi2, ..., k),
    adequacy and derived properties."""
    rows: list[Row] = []
    for fit in point_fits(p):
        head = [p.index, fit.lms, fit.model, fit.freq_dep, fit.method]
        derived = content.flat(content.derived_properties(fit))
        props = content.fit_properties(fit) | {f"derived_{k}": v for k, v in derived.items()}
        for name, (value, unit) in props.items():
            rows.append(head + [name, value if isinstance(value, str) else _cell(value), unit])
    return rows


def _table_files(p: Point, out: Path) -> list[Path]:
    files = []
    for fit in point_fits(p):
        d = content.fit_arrays(fit)
        if "covariance" in d:
            names = d["covariance_names"]
            unit = dict(zip(d["names"], d["units"]))
            rows: list[Row] = [["name", "unit", *names]] + [
                [n, unit[n]] + [_cell(v) for v in row] for n, row in zip(names, d["covariance"])
            ]
            files.append(out / f"covariance_{p.name}_{fit.key}.csv")
            write_atomic(files[-1], csvfile.render_rows(rows))
        derived = content.derived_columns(fit)
        if derived:
            cols = list(derived.items())
            rows = [[f"{k} [{u}]" for k, (_, u) in cols]]
            rows += [[_cell(v[i]) for _, (v, _) in cols] for i in range(len(cols[0][1][0]))]
            files.append(out / f"derived_{p.name}_{fit.key}.csv")
            write_atomic(files[-1], csvfile.render_rows(rows))
    return files


def _runout_turns_file(p: Point, out: Path) -> list[Path]:
    """runout_turns_PPPP.csv: a row per block (the orbit table's order), a column per field of
    export_content.RUNOUT_TURNS, a number's header with its unit."""
    turns = content.runout_turns_columns(p.runout_turns)
    if not turns:
        return []
    cols = list(turns.items())
    rows: list[Row] = [[f"{k} [{u}]" if u else k for k, (_, u) in cols]]
    n = len(cols[0][1][0])
    rows += [[str(v[i]) if v.dtype.kind in "Uiu" else _cell(v[i]) for _, (v, _) in cols] for i in range(n)]
    path = out / f"runout_turns_{p.name}.csv"
    write_atomic(path, csvfile.render_rows(rows))
    return [path]


def export_csv(run: Run, points: list[Point], out: Path) -> list[Path]:
    files = []
    for p in points:
        for lms, table in p.tables.items():
            path = out / f"point_{p.name}_{lms}.csv"
            write_orbit_table(path, table, units=True)  # durable: a StorageError names the file
            files.append(path)
    path = out / "coefficients.csv"
    write_atomic(path, csvfile.render([row for p in points for row in csvfile.point_rows(p, run.sim)]))
    files.append(path)
    files.append(out / "fits.csv")
    write_atomic(files[-1], csvfile.render_rows([FIT_HEAD] + [r for p in points for r in _fit_rows(p, run.sim)]))
    files.append(out / "fit_properties.csv")
    write_atomic(files[-1], csvfile.render_rows([PROPERTY_HEAD] + [r for p in points for r in _property_rows(p)]))
    for p in points:
        files += _table_files(p, out) + _runout_turns_file(p, out)
    files.append(out / "provenance.csv")
    write_atomic(
        files[-1], csvfile.render_rows([["key", "value"]] + [[k, v] for k, v in content.provenance(run).items()])
    )
    return files
