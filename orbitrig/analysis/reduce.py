"""Identify again from a run's stored orbit tables, without the rig.

`reduce_run` runs :func:`reduction.identify.identify` on the orbit table of
every complete operating point, for both load measuring systems, with one
model / frequency dependence / method. The run's own results (``run.h5``, the pieces) and
``coefficients.csv`` are never touched: `write_csv` writes a separate file
``DIR/reduce_<model>_<freq-dep>_<method>.csv`` with the columns of
``coefficients.csv`` (docs/storage.md) but the expanded uncertainties ``_U`` (reduce makes no
budget), one row per (point, lms).

Its ``not_determined`` column has coefficients.csv's name but not its test: it lists the
coefficients whose statistical expanded uncertainty (the identification's ``not_determined``:
k times the standard error, k of reduction.statistics.coverage_factor, 2 with u_*) exceeds
their magnitude, where coefficients.csv's lists those whose expanded uncertainty U (the same
k, calibration included when the rig states it) does. The two can differ for the same fit.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from orbitrig.analysis.rounding import at_decimals, number, uncertainty_decimals, with_uncertainty
from orbitrig.errors import IdentificationError, ReductionError
from orbitrig.load_systems import LMS, LoadSystem
from orbitrig.store.reader import freq_dep_key
from orbitrig.store.stored_run import Point, Run, StoredIdentification
from orbitrig.store.csvfile import (
    CSV_HEAD,
    coef_order,
    coefficient_column,
    fit_truth,
    one_line,
    render_table,
    true_entry,
    warnings_cell,
)
from orbitrig.store.durable import write_atomic
from orbitrig.store.layout import point_cell
from reduction.methods import Method
from rigunits import MPA, display_unit

#: constant-term keys in the spec's order
CONSTANT_KEYS = tuple(f"{m}{e}" for m in "KCD" for e in ("xx", "xy", "yx", "yy"))


@dataclass
class Reduced:
    """The result of one (point, lms): an Identification, or the refusal message."""

    point: Point
    lms: LoadSystem
    model: str
    freq_dep: str
    method: Method | str  # (a stored fit's: as the run's files name it)
    identification: Any = None  # reduction.identify.Identification
    error: str | None = None
    stored: dict[str, Any] | None = None  # the sweep's stored JSON of this identification, if repeated

    def to_dict(self) -> dict[str, Any]:
        head = {"point": self.point.index, "label": self.point.settings.label, "lms": self.lms}
        if self.identification is None:
            return {**head, "model": self.model, "freq_dep": self.freq_dep, "method": self.method, "error": self.error}
        return {**head, **self.identification.to_dict()}


def identify_point(
    point: Point, lms: LoadSystem, model: str, freq_dep: str = "none", method: Method | str = Method.OLS
) -> Reduced:
    """Identify one point's orbit table of one LMS (``method``: a Method or its name, checked by
    reduction.identify). A refused model (IdentificationError) is returned as ``error``; a bad
    option (other ReductionError) is raised."""
    from reduction.identify import identify

    row = Reduced(point, lms, model, freq_dep, method)
    try:
        row.identification = identify(point.tables[lms], model=model, freq_dep=freq_dep, method=method)
    except IdentificationError as err:
        row.error = str(err)
    return row


def reidentify(point: Point, stored: StoredIdentification) -> Reduced:
    """Repeat one of the sweep's stored identifications from the stored table."""
    row = identify_point(point, stored.lms, stored.model, stored.freq_dep, stored.method)
    row.stored = stored.result
    return row


def reduce_run(
    run: Run,
    model: str,
    freq_dep: str = "none",
    method: Method | str = Method.OLS,
    lms_names: tuple[LoadSystem, ...] = LMS,
    points: list[Point] | None = None,
) -> list[Reduced]:
    """Identify every complete point of ``run`` (or those of ``points``, e.g. a
    orbitrig.store.selection.Selection's) for each LMS that has a table.

    A model a table cannot identify is kept as that row's ``error``. Raises
    ReductionError for an unknown model / spec / method (checked first, by
    reduction.identify.check_options) and when the run holds no complete point.
    """
    from reduction.identify import check_options

    check_options(model, freq_dep, method)
    chosen = run.complete_points if points is None else points
    with_table = [p for p in chosen if any(lms in p.tables for lms in lms_names)]
    if not with_table:
        raise ReductionError(
            f"{run.directory}: no complete operating point with an orbit table (run status: {run.status})"
        )
    return [
        identify_point(point, lms, model, freq_dep, method)
        for point in with_table
        for lms in lms_names
        if lms in point.tables
    ]


def csv_path(directory: str | Path, model: str, freq_dep: str, method: Method | str) -> Path:
    """``DIR/reduce_<model>_<freq-dep>_<method>.csv`` (':' and ',' of the spec -> '_')."""
    return Path(directory) / f"reduce_{model}_{freq_dep_key(freq_dep)}_{method}.csv"


def true_constants(point: Point) -> dict[str, float]:
    """The simulator's true constant-term coefficients (K0, C0, D0), keyed Kxx..Dyy."""
    truth = point.truth or {}
    return {k: true_entry(truth, k) for k in CONSTANT_KEYS if f"{k[0]}0" in truth}


def fit_true_values(r: Reduced) -> dict[str, float]:
    """The simulator's truth of `r`'s fit, keyed as its coefficients: the true Z projected onto
    its model (reduction.expected, as the sweep stores it) when the run stored Z, else the
    constant best fit (constant terms only); {} for a refused model or a run without truth."""
    from reduction.errors import ReductionError
    from reduction.expected import noise_free_fit

    truth = r.point.truth
    if r.identification is None or not truth:
        return {}
    if "Z_re" in truth:
        z = np.asarray(truth["Z_re"], dtype=float) + 1j * np.asarray(truth["Z_im"], dtype=float)
        try:
            return noise_free_fit(r.identification, r.point.tables[r.lms], z)
        except (ReductionError, np.linalg.LinAlgError, ValueError):
            pass
    constant = true_constants(r.point)
    return {k: constant[k] for k in r.identification.coefficients if k in constant}


def own_truth(r: Reduced) -> dict[str, float]:
    """The truth the report sets beside fit `r` (its table and its coefficient figure): the
    sweep's stored own truth of the fit when there is one, else :func:`fit_true_values`."""
    if ((r.stored or {}).get("truth") or {}).get("coefficients"):
        return fit_truth(r.stored, r.point.truth)
    return fit_true_values(r) if "Z_re" in (r.point.truth or {}) else {}


def csv_rows(rows: list[Reduced], sim: bool) -> tuple[list[str], list[dict[str, Any]]]:
    """Columns and rows in the layout of coefficients.csv (docs/storage.md, orbitrig.store.writer):
    settings, result columns, every coefficient and its `_std`, and in --sim runs `true_K`
    (fit_true_values: each fit's own truth); no `_U`, and `not_determined` by the fit's own
    statistical U, not the combined one (see the module's docstring); ``warnings`` joined as coefficients.csv's."""
    keys: list[str] = []
    for r in rows:
        if r.identification is not None:
            keys += [k for k in r.identification.coefficients if k not in keys]
    keys.sort(key=coef_order)
    trues = [fit_true_values(r) if sim else {} for r in rows]
    columns = [*CSV_HEAD, *(coefficient_column(k, kind) for k in keys for kind in ("", "std"))]
    columns += [coefficient_column(k, "true") for k in keys if any(k in t for t in trues)]
    out = []
    for r, true in zip(rows, trues):
        s = r.point.settings
        d: dict[str, Any] = {
            "point": r.point.index,
            "label": s.label,
            "spin_rpm": s.spin_rpm,
            "recess_pressure_mpa": s.recess_pressure / MPA,
            "pressure_ratio": s.pressure_ratio,
            "static_eccentricity": s.static_eccentricity,
            "dynamic_eccentricity": s.dynamic_eccentricity,
            "lms": r.lms,
            "model": r.model,
            "freq_dep": r.freq_dep,
            "method": r.method,
            "error": one_line(r.error or ""),
            "not_determined": " ".join(r.identification.not_determined if r.identification is not None else []),
            "warnings": warnings_cell(r.identification.warnings if r.identification is not None else ()),
        }
        ident = r.identification
        if ident is not None:
            d.update(
                {
                    "n_frequencies": ident.n_frequencies,
                    "condition_number": ident.condition_number,
                    "residual_rms [N]": ident.residual_rms,
                }
            )
            for k in keys:
                d[coefficient_column(k)] = ident.coefficients.get(k)
                d[coefficient_column(k, "std")] = ident.std_errors.get(k)
            d.update({coefficient_column(k, "true"): v for k, v in true.items()})
        out.append({c: "" if d.get(c) is None else d[c] for c in columns})
    return columns, out


def write_csv(path: str | Path, rows: list[Reduced], sim: bool) -> Path:
    """Write the reduce results durably (coefficients.csv's writer; a StorageError names the file)."""
    path = Path(path)
    write_atomic(path, render_table(*csv_rows(rows, sim)))
    return path


def table_cells(rows: list[Reduced], full: bool = False) -> list[list[str]]:
    """The header and the rows (cells as text) of a table of the constant terms and the residual
    (N; and the exponent M that power:auto chose). Text: each term '12.35 ± 0.12' in MN/m,
    kN s/m or kg, its standard error to 2 significant digits and the value to the same decimal
    (rounding.with_uncertainty); `full`: in SI (N/m, N s/m, kg), each term followed by its
    ``_std`` column, every number the shortest decimal that reads back as the same double, the
    tail named residual_rms and exponent (as in the CSV written and the JSON). A refused
    (point, lms) shows 'refused' (the reason goes to standard error). In --sim runs each fit is
    followed by a row 'true (LMS)' of its own truth (fit_true_values: the true Z projected onto
    the fit's model, as the CSV's true_* columns), in text to the fit's decimals. The point is
    named as on the terminal ('0003', Point.name) in text and by its index ('3') in `full`, as
    every CSV file of a run carries it (coefficients.csv, reduce_*.csv, the exports)."""
    cols = [k for k in CONSTANT_KEYS if any(r.identification and k in r.identification.coefficients for r in rows)]
    auto = any(r.identification is not None and r.identification.exponent is not None for r in rows)
    if full:
        head = [coefficient_column(k, kind) for k in cols for kind in ("", "std")]
        tail = ["residual_rms [N]", "exponent [1]"]
    else:
        head = [f"{k} [{display_unit(k)[0]}]" for k in cols]
        tail = ["resid [N]", "M"]
    lines = [["point", "lms", *head, tail[0], *(tail[1:] if auto else [])]]
    for r in rows:
        ident = r.identification
        point = point_cell(r.point.index, full)
        lines.append([point, str(r.lms), *(["refused"] if ident is None else _fit_cells(ident, cols, full, auto))])
        truth = fit_true_values(r)
        if truth:
            lines.append([point, f"true ({r.lms})", *_true_cells(truth, ident, cols, full)])
    return lines


def _fit_cells(ident: Any, cols: list[str], full: bool, auto: bool) -> list[str]:
    """A fit's cells of :func:`table_cells`: each term (and its std, `full`), the residual, M."""
    cells = []
    for k in cols:
        value, std = ident.coefficients[k], ident.std_errors.get(k)
        if full:
            cells += [number(value, full=True), number(std, full=True)]
        else:
            scale = display_unit(k)[1]
            cells.append(with_uncertainty(value * scale, None if std is None else std * scale))
    cells.append(number(ident.residual_rms, full=True) if full else f"{ident.residual_rms:.3g}")
    return cells + ([str(ident.exponent)] if auto else [])


def _true_cells(truth: dict[str, float], ident: Any, cols: list[str], full: bool) -> list[str]:
    """The cells of a fit's true row: SI in full (its std cells empty), or to the fit's decimals."""
    if full:
        return [cell for k in cols for cell in ((number(truth[k], full=True) if k in truth else ""), "")]
    cells = []
    for k in cols:
        scale = display_unit(k)[1]
        std = ident.std_errors.get(k)
        decimals = uncertainty_decimals(None if std is None else std * scale)
        cells.append(at_decimals(truth[k] * scale, decimals) if k in truth else "")
    return cells


def table_legend(rows: list[Reduced]) -> list[str]:
    """What the text table's columns and rows are: the residual, the constant terms of a
    frequency-dependent fit, power:auto's exponent M, the simulator's truth."""
    from reduction.models import is_constant

    lines = [
        "K, C, D: value \u00b1 its standard error (k = 1, statistical: the fit's, no calibration; the CSV's "
        "_std), to 2 significant digits of the error and the value to the same decimal; units in the header",
        "resid = RMS of measured minus reproduced force over the table's equations (N)",
    ]
    freq_dep = rows[0].freq_dep if rows else "none"
    if not is_constant(freq_dep):
        lines.append(
            f"{freq_dep}: K, C, D shown are the constant terms (Omega^0); every term is in the CSV written, "
            "its unit in the header (Kxx_1 [N/m (rad/s)^-1])"
        )
    if any(r.identification is not None and r.identification.exponent is not None for r in rows):
        lines.append("M = the exponent power:auto chose: K = K0 + Omega^M KM, likewise C and D (Omega in rad/s)")
    if any(fit_true_values(r) for r in rows):
        lines.append(
            "true (LMS) = the simulator's true Z projected onto the fit's model (the CSV's true_* columns), "
            "to the decimals of the fit above"
        )
    return lines
