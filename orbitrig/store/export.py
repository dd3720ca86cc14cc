"""`orbitrig export RUN`: a run's orbit tables and results in formats other tools read.

For every complete operating point and load measuring system the orbit table (the
columns of the orbit-table CSV, with n_records and u_* when measured) and the results
(the columns of coefficients.csv; in .mat and .h5 also intervals and covariances):

- ``csv``: ``point_PPPP_<lms>.csv`` per table and ``coefficients.csv``;
- ``mat``: ``run.mat`` (MATLAB, scipy.io.savemat): struct ``points.pPPPP``;
- ``tdms``: ``run.tdms`` (NI LabVIEW, npTDMS): a group per table, a ``coefficients`` group;
- ``h5``: ``run.h5``, the consolidated single file (docs/storage.md).

Every file is written to a temporary name and renamed into place; every failure
is a StorageError naming the file.
"""

from __future__ import annotations

import io
import os
import re
from pathlib import Path

import numpy as np

from orbitrig.store import csvfile
from orbitrig.store.durable import write_atomic
from orbitrig.store.errors import StorageError, storage_error
from orbitrig.store.layout import LMS_ORDER, RunLayout, coefficient_si_unit
from orbitrig.store.orbit_table import orbit_table_columns, write_orbit_table
from orbitrig.store.reader import Point, Run, StoredIdentification, read_run

FORMATS = ("csv", "mat", "tdms", "h5")
EXPORT_DIR = "export"


def export_run(directory: str | Path, fmt: str, out: str | Path | None = None) -> list[Path]:
    """Write the export of the run in `directory` as `fmt` into `out` (default DIR/export).
    Returns the files written. Raises RunDirError (not a run) or StorageError."""
    if fmt not in FORMATS:
        raise ValueError(f"unknown format {fmt!r}: one of {', '.join(FORMATS)}")
    layout = RunLayout(Path(directory))
    out = Path(out) if out is not None else layout.dir / EXPORT_DIR
    if fmt == "h5":
        run = read_run(layout.dir)  # a RunDirError for what is not a run
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise storage_error(out, "create the export directory", err) from err
        return [_export_h5(layout, out)]
    run = read_run(layout.dir)
    points = [p for p in run.complete_points if p.tables]
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise storage_error(out, "create the export directory", err) from err
    return {"csv": _export_csv, "mat": _export_mat, "tdms": _export_tdms}[fmt](run, points, out)


def _export_h5(layout: RunLayout, out: Path) -> Path:
    from orbitrig.store.consolidate import write_run_file

    path = out / layout.run_file.name
    if layout.has_pieces():
        return write_run_file(layout, path)
    else:  # a directory holding only run.h5: copy it
        try:
            data = layout.run_file.read_bytes()
        except OSError as err:
            raise storage_error(layout.run_file, "read", err) from err
    if path.resolve() != layout.run_file.resolve():
        write_atomic(path, data)
    return path


def _export_csv(run: Run, points: list[Point], out: Path) -> list[Path]:
    files = []
    for p in points:
        for lms, table in p.tables.items():
            path = out / f"point_{p.name}_{lms}.csv"
            tmp = path.with_name(path.name + ".tmp")
            try:
                write_orbit_table(tmp, table)
                os.replace(tmp, path)
            except OSError as err:
                tmp.unlink(missing_ok=True)
                raise storage_error(path, "write", err) from err
            files.append(path)
    path = out / "coefficients.csv"
    write_atomic(path, csvfile.render([row for p in points for row in csvfile.point_rows(p, run.sim)]))
    return files + [path]


def _field(name: str) -> str:
    """A MATLAB struct field name: letters, digits, '_', starting with a letter, <= 63 chars."""
    name = re.sub(r"\W", "_", name)
    return (name if name[:1].isalpha() else f"f_{name}")[:63]


def _cell(values) -> np.ndarray:
    """A MATLAB cell array of strings."""
    items = [str(v) for v in values]
    arr = np.empty(len(items), dtype=object)
    arr[:] = items
    return arr


def _identification_struct(ident: StoredIdentification) -> dict:
    d = ident.result or {}
    names = list(d.get("coefficients", {}))
    s = {"lms": ident.lms, "model": ident.model, "freq_dep": ident.freq_dep, "method": ident.method,
         "error": ident.error or "", "names": _cell(names), "units": _cell(coefficient_si_unit(k) for k in names)}
    num = lambda m, k: np.nan if (m or {}).get(k) is None else float(m[k])  # noqa: E731
    s["coefficients"] = np.array([num(d.get("coefficients"), k) for k in names])
    s["std_errors"] = np.array([num(d.get("std_errors"), k) for k in names])
    ci = d.get("confidence_95") or {}
    s["interval_95"] = np.array([[np.nan if v is None else float(v) for v in (ci.get(k) or (None, None))]
                                 for k in names]).reshape(-1, 2)  # fmt: skip
    if d.get("covariance") is not None:
        s["free"] = _cell(d.get("free") or [])
        s["covariance"] = np.array([[np.nan if v is None else float(v) for v in r] for r in d["covariance"]])
    for k in ("n_frequencies", "condition_number", "residual_rms", "dof", "chi2", "p_value"):
        if k in d:
            s[k] = np.nan if d[k] is None else float(d[k])
    s["notes"], s["warnings"] = _cell(d.get("notes") or []), _cell(d.get("warnings") or [])
    return s


def _point_struct(p: Point) -> dict:
    st = p.settings
    s = {"index": p.index, "label": st.label, "spin_rpm": st.spin_rpm, "spin": st.spin,
         "recess_pressure": st.recess_pressure, "pressure_ratio": st.pressure_ratio,
         "static_eccentricity": st.static_eccentricity, "dynamic_eccentricity": st.dynamic_eccentricity,
         "orbit_radius": st.orbit_radius}  # fmt: skip
    for lms, table in p.tables.items():
        cols = orbit_table_columns(table)
        t = {"orbit": np.asarray(table.orbit, dtype=float), "orbit_hz": cols["orbit_hz"][0]}
        t.update(table.phasors)
        t.update({k: v for k, (v, _) in cols.items() if k.startswith(("gamma2", "n_records", "u_"))})
        s[lms] = t
    s["identification"] = {_field(f"{i.lms}__{i.model}__{i.freq_dep}__{i.method}"): _identification_struct(i)
                           for i in p.identifications}  # fmt: skip
    return s


MAT_UNITS = {
    "spin": "rad/s", "spin_rpm": "rpm", "recess_pressure": "Pa", "orbit_radius": "m", "orbit": "rad/s",
    "orbit_hz": "Hz", "x": "m (complex phasor, q = Re(q_bar exp(i Omega t)))", "y": "m (complex phasor)",
    "fx": "N (complex phasor, force on the journal)", "fy": "N (complex phasor)", "gamma2": "1", "u": "m or N",
    "coefficients": "SI, see identification.units", "covariance": "SI products of the coefficients' units",
}  # fmt: skip


def _export_mat(run: Run, points: list[Point], out: Path) -> list[Path]:
    from scipy.io import savemat

    data = {
        "run": {"directory": str(run.directory), "status": run.status, "status_message": run.status_message,
                "sim": run.sim, "matrix_name": run.matrix_name, "created": run.created,
                "channels": _cell(run.channels), "channel_units": _cell(run.channel_units)},
        "units": MAT_UNITS,
        "points": {f"p{p.name}": _point_struct(p) for p in points},
    }  # fmt: skip
    buf = io.BytesIO()
    try:
        savemat(buf, data, long_field_names=True, do_compression=True, oned_as="column")
    except (ValueError, TypeError) as err:
        raise StorageError(out / "run.mat", f"cannot build the MATLAB file: {err}") from err
    path = out / "run.mat"
    write_atomic(path, buf.getvalue())
    return [path]


def _export_tdms(run: Run, points: list[Point], out: Path) -> list[Path]:
    from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

    objects = [RootObject({"title": f"orbitrig run {run.directory.name}", "status": run.status,
                           "matrix_name": run.matrix_name, "sim": str(run.sim)})]  # fmt: skip
    for p in points:
        st = p.settings
        for lms in [k for k in LMS_ORDER if k in p.tables] + [k for k in p.tables if k not in LMS_ORDER]:
            group = f"point {p.name} {lms}"
            objects.append(GroupObject(group, {"label": st.label, "spin_rpm": st.spin_rpm,
                                               "recess_pressure_Pa": st.recess_pressure,
                                               "pressure_ratio": st.pressure_ratio,
                                               "static_eccentricity": st.static_eccentricity,
                                               "dynamic_eccentricity": st.dynamic_eccentricity}))  # fmt: skip
            for name, (values, unit) in orbit_table_columns(p.tables[lms]).items():
                objects.append(ChannelObject(group, name, np.asarray(values), {"unit_string": unit}))
    rows = [row for p in points for row in csvfile.point_rows(p, run.sim)]
    objects.append(GroupObject("coefficients", {"description": "the columns of coefficients.csv"}))
    for col in csvfile.columns(rows):
        cells = [str(r.get(col, "")) for r in rows]
        unit = col[col.index("[") + 1: -1] if col.endswith("]") else ""
        name = col.split(" [")[0]
        if col in ("label", "lms", "model", "freq_dep", "method", "error"):
            values = np.array(cells, dtype=str)
        else:
            values = np.array([float(c) if c else np.nan for c in cells], dtype=np.float64)
        objects.append(ChannelObject("coefficients", name, values, {"unit_string": unit}))
    path = out / "run.tdms"
    buf = io.BytesIO()
    try:
        with TdmsWriter(buf) as writer:
            writer.write_segment(objects)
    except (ValueError, TypeError) as err:
        raise StorageError(path, f"cannot build the TDMS file: {err}") from err
    write_atomic(path, buf.getvalue())
    return [path]
