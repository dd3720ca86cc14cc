"""Identify again from a run's stored orbit tables, without the rig.

`reduce_run` runs :func:`reduction.identify.identify` on the orbit table of
every complete operating point, for both load measuring systems, with one
model / frequency dependence / method. The run's own results in ``run.h5`` and
``coefficients.csv`` are never touched: `write_csv` writes a separate file
``DIR/reduce_<model>_<freq-dep>_<method>.csv`` with the columns of
``coefficients.csv`` (docs/storage.md), one row per (point, lms).
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from orbitrig.errors import IdentificationError, ReductionError
from orbitrig.run_reader import LMS_NAMES, Point, Run, StoredIdentification, freq_dep_key

#: constant-term keys in the spec's order (the `true_` columns)
CONSTANT_KEYS = tuple(f"{m}{e}" for m in "KCD" for e in ("xx", "xy", "yx", "yy"))
SETTING_COLUMNS = (
    "point", "label", "spin_rpm", "recess_pressure_mpa", "pressure_ratio",
    "static_eccentricity", "dynamic_eccentricity",
)  # fmt: skip
RESULT_COLUMNS = (
    "lms", "model", "freq_dep", "method", "n_frequencies", "condition_number", "residual_rms", "error",
)  # fmt: skip


@dataclass
class Reduced:
    """The result of one (point, lms): an Identification, or the refusal message."""

    point: Point
    lms: str
    model: str
    freq_dep: str
    method: str
    identification: Any = None  # reduction.identify.Identification
    error: str | None = None

    def to_dict(self) -> dict[str, Any]:
        head = {"point": self.point.index, "label": self.point.settings.label, "lms": self.lms}
        if self.identification is None:
            return {**head, "model": self.model, "freq_dep": self.freq_dep, "method": self.method, "error": self.error}
        return {**head, **self.identification.to_dict()}


def identify_point(point: Point, lms: str, model: str, freq_dep: str = "none", method: str = "ols") -> Reduced:
    """Identify one point's orbit table of one LMS. A refused model (IdentificationError)
    is returned as ``error``; a bad option (other ReductionError) is raised."""
    from reduction.identify import identify

    row = Reduced(point, lms, model, freq_dep, method)
    try:
        row.identification = identify(point.tables[lms], model=model, freq_dep=freq_dep, method=method)
    except IdentificationError as err:
        row.error = str(err)
    return row


def reidentify(point: Point, stored: StoredIdentification) -> Reduced:
    """Repeat one of the sweep's stored identifications from the stored table."""
    return identify_point(point, stored.lms, stored.model, stored.freq_dep, stored.method)


def reduce_run(
    run: Run,
    model: str,
    freq_dep: str = "none",
    method: str = "ols",
    lms_names: tuple[str, ...] = LMS_NAMES,
) -> list[Reduced]:
    """Identify every complete point of ``run`` for each LMS that has a table.

    Raises ReductionError for an unknown model / spec / method (checked on the
    first table), and ValueError when the run holds no complete point.
    """
    points = [p for p in run.complete_points if any(lms in p.tables for lms in lms_names)]
    if not points:
        raise ReductionError(
            f"{run.directory / 'run.h5'}: no complete operating point with an orbit table "
            f"(run status: {run.status})"
        )
    return [
        identify_point(point, lms, model, freq_dep, method)
        for point in points
        for lms in lms_names
        if lms in point.tables
    ]


def csv_path(directory: str | Path, model: str, freq_dep: str, method: str) -> Path:
    """``DIR/reduce_<model>_<freq-dep>_<method>.csv`` (':' and ',' of the spec -> '_')."""
    return Path(directory) / f"reduce_{model}_{freq_dep_key(freq_dep)}_{method}.csv"


def true_constants(point: Point) -> dict[str, float]:
    """The simulator's true constant-term coefficients (K0, C0, D0), keyed Kxx..Dyy."""
    truth = point.truth or {}
    out: dict[str, float] = {}
    for m in "KCD":
        mat = truth.get(f"{m}0")
        if mat is None:
            continue
        for i, e in enumerate(("xx", "xy", "yx", "yy")):
            out[f"{m}{e}"] = float(mat[i // 2][i % 2])
    return out


def _num(value: Any) -> Any:
    return "" if value is None or (isinstance(value, float) and math.isnan(value)) else value


def csv_rows(rows: list[Reduced], sim: bool) -> tuple[list[str], list[dict[str, Any]]]:
    """Columns and rows in the layout of coefficients.csv (docs/storage.md)."""
    keys: list[str] = []
    for r in rows:
        if r.identification is not None:
            keys += [k for k in r.identification.coefficients if k not in keys]
    columns = [*SETTING_COLUMNS, *RESULT_COLUMNS]
    for k in keys:
        columns += [k, f"{k}_std"]
    if sim:
        columns += [f"true_{k}" for k in CONSTANT_KEYS]
    out = []
    for r in rows:
        s = r.point.settings
        d: dict[str, Any] = {
            "point": r.point.index, "label": s.label, "spin_rpm": s.spin_rpm,
            "recess_pressure_mpa": s.recess_pressure / 1e6, "pressure_ratio": s.pressure_ratio,
            "static_eccentricity": s.static_eccentricity, "dynamic_eccentricity": s.dynamic_eccentricity,
            "lms": r.lms, "model": r.model, "freq_dep": r.freq_dep, "method": r.method,
            "error": r.error or "",
        }  # fmt: skip
        ident = r.identification
        if ident is not None:
            d.update(
                n_frequencies=ident.n_frequencies,
                condition_number=ident.condition_number,
                residual_rms=ident.residual_rms,
            )
            for k in keys:
                d[k] = ident.coefficients.get(k)
                d[f"{k}_std"] = ident.std_errors.get(k)
        if sim:
            d.update({f"true_{k}": v for k, v in true_constants(r.point).items()})
        out.append({c: _num(d.get(c)) for c in columns})
    return columns, out


def write_csv(path: str | Path, rows: list[Reduced], sim: bool) -> Path:
    """Write the reduce results; the file is replaced atomically."""
    path = Path(path)
    columns, data = csv_rows(rows, sim)
    tmp = path.with_name(path.name + ".tmp")
    with tmp.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=columns)
        writer.writeheader()
        writer.writerows(data)
    tmp.replace(path)
    return path


def format_table(rows: list[Reduced]) -> str:
    """A terminal table of the constant terms: K in MN/m, C in kN s/m, D in kg."""
    cols = [k for k in CONSTANT_KEYS if any(r.identification and k in r.identification.coefficients for r in rows)]
    scale = {"K": 1e-6, "C": 1e-3, "D": 1.0}
    units = {"K": "MN/m", "C": "kN s/m", "D": "kg"}
    head = ["point", "lms"] + [f"{k} [{units[k[0]]}]" for k in cols] + ["resid [N]"]
    lines = []
    for r in rows:
        cells = [f"{r.point.index:04d}", r.lms]
        if r.identification is None:
            cells.append(f"refused: {r.error}")
        else:
            c = r.identification.coefficients
            cells += [f"{c[k] * scale[k[0]]:.4g}" for k in cols]
            cells.append(f"{r.identification.residual_rms:.3g}")
        lines.append(cells)
    widths = [max(len(head[i]), *(len(ln[i]) for ln in lines if i < len(ln) and len(ln) == len(head))) for i in range(len(head))]
    fmt = lambda cells: "  ".join(c.rjust(w) if i > 1 else c.ljust(w) for i, (c, w) in enumerate(zip(cells, widths)))  # noqa: E731
    out = [fmt(head)]
    for ln in lines:
        out.append(fmt(ln) if len(ln) == len(head) else "  ".join([ln[0].ljust(widths[0]), ln[1].ljust(widths[1]), ln[2]]))
    return "\n".join(out)
