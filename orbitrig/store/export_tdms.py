"""``orbitrig export --format tdms``: run.tdms (NI TDMS, LabVIEW; written with npTDMS).

Every channel has ``unit_string``; properties are numbers (with a ``<name>.unit_string``
property beside each) or text. Groups: ``point PPPP <lms>`` (the orbit table and
``direction``; the settings as properties), ``coefficients`` (the columns of
coefficients.csv and ``KEY_U``), ``fit PPPP <key>`` (name, unit, value, std, U, budget,
e_n per coefficient; k and the adequacy as properties), ``covariance PPPP <key>`` (one
channel per free coefficient, ``name`` the rows), ``derived PPPP <key>``, ``truth PPPP``
(K0, C0, D0 row-major, Z_re, Z_im, orbit) and ``waveforms PPPP FF_dir`` (each A/D
channel's averaged revolution and ``<channel>_theta``; dc, phasor and uncertainty as
channel properties).
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from orbitrig.store import csvfile
from orbitrig.store import export_content as content
from orbitrig.store.durable import write_atomic
from orbitrig.store.errors import StorageError
from orbitrig.store.fit_record import BUDGET_PARTS, point_fits
from orbitrig.load_systems import LMS


_TEXT = {"unit_string": ""}  # a text channel


def _numeric(props: dict[str, tuple[float, str]]) -> dict:
    out = {}
    for name, (value, unit) in props.items():
        out[name], out[f"{name}.unit_string"] = value, unit
    return out


def _channels(group: str, columns: dict[str, tuple[np.ndarray, str]]) -> list:
    from nptdms import ChannelObject

    return [
        ChannelObject(group, name, np.asarray(values), {"unit_string": unit})
        for name, (values, unit) in columns.items()
    ]


def _fit_objects(p, fit) -> list:
    from nptdms import ChannelObject, GroupObject

    d = content.fit_arrays(fit)
    group = f"fit {p.name} {fit.key}"
    props = {"error": fit.error, "adequacy_verdict": d.get("adequacy_verdict", "")}
    props |= _numeric(
        {
            k: (float(np.ravel(v)[0]) if np.size(v) == 1 else str(list(np.ravel(v))), "1")
            for k, v in d.items()
            if k == "k" or (k.startswith("adequacy_") and k != "adequacy_verdict")
        }
    )
    objs = [
        GroupObject(group, props),
        ChannelObject(group, "name", np.array(fit.names, dtype=str), _TEXT),
        ChannelObject(group, "unit", np.array(fit.units, dtype=str), _TEXT),
    ]
    per_row = {"value": d["value"], "std": d["std"], "U": d["U"]}
    per_row |= {part: d[part] for part in (*BUDGET_PARTS, "e_n") if part in d}
    objs += [
        ChannelObject(group, k, np.asarray(v, dtype=float), {"unit_string": "1" if k == "e_n" else "see unit"})
        for k, v in per_row.items()
    ]
    if "covariance" in d:
        cg = f"covariance {p.name} {fit.key}"
        unit = dict(zip(fit.names, fit.units))
        objs += [
            GroupObject(cg, {"description": "covariance; entry (row, column) in unit(row) x unit(column)"}),
            ChannelObject(cg, "name", np.array(d["covariance_names"], dtype=str), _TEXT),
        ]
        objs += [
            ChannelObject(cg, n, d["covariance"][:, j], {"unit_string": f"({unit[n]}) x unit(row)"})
            for j, n in enumerate(d["covariance_names"])
        ]
    derived = content.derived_columns(fit)
    if derived:
        objs += [GroupObject(f"derived {p.name} {fit.key}", {})] + _channels(f"derived {p.name} {fit.key}", derived)
    return objs


def _point_objects(p, channels: list[str], channel_units: list[str]) -> list:
    from nptdms import ChannelObject, GroupObject

    objs = []
    settings = _numeric(content.settings(p)) | {"label": p.settings.label}
    for lms in [k for k in LMS if k in p.tables]:
        group = f"point {p.name} {lms}"
        objs += [GroupObject(group, settings)] + _channels(group, content.table_columns(p.tables[lms]))
    for fit in point_fits(p):
        objs += _fit_objects(p, fit)
    truth = content.truth_arrays(p.truth)
    if truth:
        flat = {k: (np.ravel(v), u) for k, (v, u) in truth.items() if k != "Z"}
        if "Z" in truth:
            z, unit = truth["Z"]
            flat |= {"Z_re": (np.ravel(z.real), unit), "Z_im": (np.ravel(z.imag), unit)}
        objs += [GroupObject(f"truth {p.name}", {"layout": "2 x 2 matrices row-major; Z: row, force, displacement"})]
        objs += _channels(f"truth {p.name}", flat)
    for b in content.waveform_arrays(p, channels):
        group = f"waveforms {p.name} {b['name']}"
        objs.append(
            GroupObject(
                group,
                _numeric(
                    {
                        "orbit_hz": (b["orbit_hz"], "Hz"),
                        "direction": (b["direction"], "1"),
                        "n_records": (b["n_records"], "1"),
                    }
                ),
            )
        )
        for c, (name, unit) in enumerate(zip(channels, channel_units)):
            props = {"unit_string": unit}
            props |= {k: float(b[k][c]) for k in ("dc", "uncertainty") if k in b}
            if "phasors" in b:
                props |= {"phasor_re": float(b["phasors"][c].real), "phasor_im": float(b["phasors"][c].imag)}
            objs += [
                ChannelObject(group, name, b["mean"][c], props),
                ChannelObject(group, f"{name}_theta", b["theta"][c], {"unit_string": "rad"}),
            ]
    return objs


def _coefficient_objects(run, points) -> list:
    from nptdms import ChannelObject, GroupObject

    rows = [row for p in points for row in csvfile.point_rows(p, run.sim)]
    objs = [GroupObject("coefficients", {"description": "the columns of coefficients.csv"})]
    for col in csvfile.columns(rows):
        cells = [str(r.get(col, "")) for r in rows]
        unit = col[col.index("[") + 1 : -1] if col.endswith("]") else ""
        if col in ("label", "lms", "model", "freq_dep", "method", "error", "not_determined"):
            values = np.array(cells, dtype=str)
        else:
            values = np.array([float(c) if c else np.nan for c in cells], dtype=np.float64)
        objs.append(ChannelObject("coefficients", col.split(" [")[0], values, {"unit_string": unit}))
    return objs


def export_tdms(run, points: list, out: Path) -> list[Path]:
    from nptdms import RootObject, TdmsWriter

    objects = [
        RootObject({"title": f"orbitrig run {run.directory.name}", **content.provenance(run), "sim": bool(run.sim)})
    ]
    for p in points:
        objects += _point_objects(p, run.channels, run.channel_units)
    objects += _coefficient_objects(run, points)
    path = out / "run.tdms"
    buf = io.BytesIO()
    try:
        with TdmsWriter(buf) as writer:
            writer.write_segment(objects)
    except (ValueError, TypeError) as err:
        raise StorageError(path, f"cannot build the TDMS file: {err}") from err
    write_atomic(path, buf.getvalue())
    return [path]
