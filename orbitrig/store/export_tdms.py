"""``orbitrig export --format tdms``: run.tdms (NI TDMS, LabVIEW; written with npTDMS).

Every channel has ``unit_string``, one unit pint parses for all its values ("1"
dimensionless, "" text); properties are numbers (with a ``<name>.unit_string`` property
beside each) or text. Groups: ``point PPPP <lms>`` (the orbit table and ``direction``; the
settings as properties), ``coefficients`` (the columns of coefficients.csv, ``warnings`` included,
and ``KEY_U``; every number to the last bit, not rounded as the CSV prints it),
``fit PPPP <key>`` (one channel per coefficient in its own unit, its rows named by the text
channel ``quantity``: value, std, U, interval_95_low, interval_95_high (value -+ U),
interval_95_statistical_low, interval_95_statistical_high (the fit's statistical-only 95 %
interval), the budget's parts, truth; e_n, not_determined and k (the coefficient's own k of U; the group's k is the largest) as channel properties; group properties: ``error`` and
``warnings`` (joined with ' | ') as text, export_content.fit_properties: dof, chi2, p_value,
aic, bic, interval (text), confidence_level, k (of U), interval_95_basis (text: combined |
statistical only) and the adequacy (verdict, test,
constant as text; its two degrees of freedom ``adequacy_dof_numerator``,
``adequacy_dof_denominator``, ``adequacy_aic_constant`` ...)), ``covariance PPPP <key>`` (the
correlation, one channel per free coefficient, ``name`` the rows, each channel's ``std``
property in its unit: covariance = r_ij std_i std_j), ``derived PPPP <key>`` (its properties
``covariance``, the basis of every _std, and ``c_eff_zero_xx_omega_0``, ``c_eff_zero_xx_std``
... in rad/s where C_eff changes sign), ``truth PPPP``
(K0, C0, D0 row-major, Z_re, Z_im, orbit), ``waveforms PPPP FF_dir`` (each A/D
channel's averaged revolution and ``<channel>_theta``; dc, phasor_re, phasor_im and
uncertainty as channel properties in the channel's unit) and ``runout_turns PPPP`` (one channel
per field of export_content.RUNOUT_TURNS, one value per block in the orbit table's row order,
each with a ``description``; ``resolved`` uint8, ``unfitted`` text).
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from orbitrig.store import csvfile
from orbitrig.store import export_content as content
from orbitrig.store.descriptions import POWER_FORM, TRUTH_CONVENTION
from orbitrig.store.durable import write_atomic
from orbitrig.store.errors import StorageError
from orbitrig.store.fit_record import BUDGET_PARTS, point_fits
from orbitrig.load_systems import LMS


_TEXT = {"unit_string": ""}  # a text channel
COVARIANCE_LAYOUT = (
    "correlation r (rows: name; one channel per free coefficient); covariance (i, j) = "
    "r_ij x std_i x std_j in unit(i) x unit(j), std and its unit_string a property of each channel"
)


def _numeric(props: dict[str, tuple[float, str]]) -> dict:
    out: dict[str, float | str] = {}
    for name, (value, unit) in props.items():
        out[name], out[f"{name}.unit_string"] = value, unit
    return out


def _properties(props: dict[str, tuple[float | str, str]]) -> dict:
    """Text as it is, each number with its ``<name>.unit_string`` (arrays flattened:
    export_content.flat)."""
    flat = content.flat(props)
    text = {k: v for k, (v, _) in flat.items() if isinstance(v, str)}
    return text | _numeric({k: (float(v), u) for k, (v, u) in flat.items() if not isinstance(v, str)})


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
    text = {"error": fit.error, "warnings": csvfile.warnings_cell(d["warnings"]), "adequacy_verdict": ""}
    props = text | _properties(content.fit_properties(fit))
    quantities: dict[str, np.ndarray] = {q: d[q] for q in ("value", "std", "U") if q in d}
    if "interval_95" in d:
        quantities |= {"interval_95_low": d["interval_95"][:, 0], "interval_95_high": d["interval_95"][:, 1]}
    if "interval_95_statistical" in d:
        stat = d["interval_95_statistical"]
        quantities |= {"interval_95_statistical_low": stat[:, 0], "interval_95_statistical_high": stat[:, 1]}
    quantities |= {q: d[q] for q in (*BUDGET_PARTS, "truth") if q in d}
    rows = list(quantities)
    objs = [GroupObject(group, props), ChannelObject(group, "quantity", np.array(rows, dtype=str), _TEXT)]
    for c, (name, unit) in enumerate(zip(fit.names, fit.units)):
        extra: dict[str, tuple[float, str]] = {k: (float(d[k][c]), "1") for k in ("e_n", "not_determined") if k in d}
        if "expanded_k" in d:
            extra["k"] = (float(d["expanded_k"][c]), "1")  # this coefficient's k of U (the group's k: the largest)
        objs.append(
            ChannelObject(
                group,
                name,
                np.array([quantities[q][c] for q in rows], dtype=float),
                {"unit_string": unit} | _numeric(extra),
            )
        )
    if "covariance" in d:
        objs += _covariance_objects(f"covariance {p.name} {fit.key}", d, dict(zip(fit.names, fit.units)))
    derived = content.derived_columns(fit)
    if derived:
        group = f"derived {p.name} {fit.key}"
        objs += [GroupObject(group, _properties(content.derived_properties(fit)))] + _channels(group, derived)
    return objs


def _covariance_objects(group: str, d: dict, unit: dict[str, str]) -> list:
    """The covariance as the correlation r (one channel per free coefficient, unit 1) and each
    coefficient's standard deviation (the channel's ``std`` property, in its unit):
    covariance (i, j) = r_ij x std_i x std_j, in unit(i) x unit(j)."""
    from nptdms import ChannelObject, GroupObject

    names, cov = d["covariance_names"], np.asarray(d["covariance"], dtype=float)
    std = np.sqrt(np.abs(np.diag(cov)))
    scale = np.outer(std, std)
    corr = np.divide(cov, scale, out=np.zeros_like(cov), where=scale > 0)
    objs = [
        GroupObject(group, {"description": COVARIANCE_LAYOUT}),
        ChannelObject(group, "name", np.array(names, dtype=str), _TEXT),
    ]
    objs += [
        ChannelObject(group, n, corr[:, j], {"unit_string": "1"} | _numeric({"std": (float(std[j]), unit[n])}))
        for j, n in enumerate(names)
    ]
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
        layout = "2 x 2 matrices row-major; Z: row, force, displacement"
        objs += [GroupObject(f"truth {p.name}", {"layout": layout, "convention": TRUTH_CONVENTION, "form": POWER_FORM})]
        objs += _channels(f"truth {p.name}", flat)
    objs += _runout_turns_objects(p)
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
            numbers: dict[str, tuple[float, str]] = {k: (float(b[k][c]), unit) for k in ("dc", "uncertainty") if k in b}
            if "phasors" in b:
                numbers |= {
                    "phasor_re": (float(b["phasors"][c].real), unit),
                    "phasor_im": (float(b["phasors"][c].imag), unit),
                }
            props = {"unit_string": unit} | _numeric(numbers)
            objs += [
                ChannelObject(group, name, b["mean"][c], props),
                ChannelObject(group, f"{name}_theta", b["theta"][c], {"unit_string": "rad"}),
            ]
    return objs


def _runout_turns_objects(p) -> list:
    """Group ``runout_turns PPPP``: one channel per field of export_content.RUNOUT_TURNS, one
    value per block in the orbit table's row order, each with its unit_string and description."""
    from nptdms import ChannelObject, GroupObject

    turns = content.runout_turns_columns(p.runout_turns)
    if not turns:
        return []
    group = f"runout_turns {p.name}"
    what = "per block, in the orbit table's row order: the spin turns per board revolution the runout is placed with"
    return [GroupObject(group, {"description": what})] + [
        ChannelObject(group, k, v, {"unit_string": u, "description": content.RUNOUT_TURNS[k][1]})
        for k, (v, u) in turns.items()
    ]


def _coefficient_objects(run, points) -> list:
    from nptdms import ChannelObject, GroupObject

    rows = [row for p in points for row in csvfile.point_rows(p, run.sim, exact=True)]
    objs = [GroupObject("coefficients", {"description": "the columns of coefficients.csv"})]
    for col in csvfile.columns(rows):
        cells = [str(r.get(col, "")) for r in rows]
        if col in csvfile.TEXT_COLUMNS:
            values = np.array(cells, dtype=str)
        else:
            values = np.array([float(c) if c else np.nan for c in cells], dtype=np.float64)
        objs.append(
            ChannelObject("coefficients", col.split(" [")[0], values, {"unit_string": csvfile.column_unit(col)})
        )
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
