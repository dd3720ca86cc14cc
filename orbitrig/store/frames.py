"""pandas and xarray views of a stored run (the Python API's tables; docs/api.md).

pandas and xarray are imported only here and only when a view is made (the `api` extra).
Columns are SI unless the name says otherwise (``spin_rpm``, ``orbit_hz``); each frame's
``attrs["units"]`` maps every column of one unit to a unit pint parses ("1": dimensionless,
"" text). A fit's coefficient table holds a unit per row instead: ``attrs["row_units"]``
(row -> unit) for the columns in ``attrs["row_unit_columns"]``; its covariance's entry
(i, j) is in ``attrs["entry_units"][i][j]`` = unit(i) x unit(j).
"""

from __future__ import annotations

import math

import numpy as np

from daq.frames import slot_angle
from orbitrig.store.csvfile import fit_cells
from orbitrig.store.fit_record import BUDGET_PARTS, FitRecord
from orbitrig.store.layout import DERIVED_UNITS, SETTINGS_UNITS, unit_product
from orbitrig.store.orbit_table import orbit_table_columns

FIT_KEYS = ("point", "lms", "model", "freq_dep", "method")


def _frame(data: dict, units: dict, index: str | list[str] | None = None):
    import pandas as pd

    df = pd.DataFrame(data)
    if index is not None:
        df = df.set_index(index)
    df.attrs["units"] = {k: v for k, v in units.items() if k in data}
    return df


def points_frame(points):
    """One row per operating point (index ``point``): settings, complete, n_frequencies."""
    rows = {k: [] for k in ("point", *SETTINGS_UNITS)}
    for p in points:
        st = p.settings
        for k in SETTINGS_UNITS:
            rows[k].append(
                len(p.frequencies) if k == "n_frequencies" else p.complete if k == "complete" else getattr(st, k)
            )
        rows["point"].append(p.index)
    return _frame(rows, SETTINGS_UNITS, "point")


def table_frame(table, blocks=()):
    """An orbit table (reduction.table.OrbitTable) in the orbit-table CSV's columns (rpm, Hz,
    m, N; gamma2_*, n_records, u_* when measured), ``direction`` (+1 forward, -1 backward) and
    ``block``: the name of the block among ``blocks`` (the point's Frequency list) each row was
    measured in, as the waveforms' ``block`` coordinate names it ("" where none is known)."""
    cols = orbit_table_columns(table, direction=True)
    data = {name: values for name, (values, _) in cols.items()}
    data["block"] = row_blocks(table.orbit, data["direction"], blocks)
    return _frame(data, {name: unit for name, (_, unit) in cols.items()} | {"block": ""})


def row_blocks(orbit, direction, blocks) -> list[str]:
    """The block of each table row (orbit > 0 in rad/s, direction +1/-1): the one whirling that
    way at that speed, the speed measured on the timing disk (or, where none was, |the planned
    one|), as the table's rows were made from them; "" unless exactly one matches."""
    speeds = [
        (b.name, b.direction, b.measured_orbit_speed if b.measured_orbit_speed > 0 else abs(b.orbit)) for b in blocks
    ]
    out = []
    for w, d in zip(np.asarray(orbit, float), direction):
        names = [n for n, bd, s in speeds if bd == d and math.isclose(s, w, rel_tol=1e-12)]
        out.append(names[0] if len(names) == 1 else "")
    return out


def coefficients_frame(fits: list[FitRecord]):
    """One row per fit: point, lms, model, freq_dep, method, error, n_frequencies,
    not_determined, warnings (as coefficients.csv: csvfile.fit_cells; a refused model's are
    <NA>, "", ""), then per coefficient KEY, KEY_std and KEY_U (expanded uncertainty), SI
    (units in attrs)."""
    import pandas as pd

    keys: list[str] = []
    for f in fits:
        keys += [k for k in f.names if k not in keys]
    data = {k: [getattr(f, k) for f in fits] for k in (*FIT_KEYS, "error")}
    data["lms"] = ["" if f.lms is None else str(f.lms) for f in fits]  # plain text, as the other key columns
    cells = [fit_cells(f.result) if f.result is not None else {} for f in fits]
    data["n_frequencies"] = pd.array([c.get("n_frequencies") for c in cells], dtype="Int64")
    data.update({k: [c.get(k, "") for c in cells] for k in ("not_determined", "warnings")})
    units = {k: "" for k in data} | {"point": "1", "n_frequencies": "1"}  # text, and the counts
    for key in keys:
        for suffix, part in (("", "value"), ("_std", "std"), ("_U", "U")):
            data[key + suffix] = [_entry(f, key, part) for f in fits]
    for f in fits:
        units.update({k + s: u for k, u in zip(f.names, f.units) for s in ("", "_std", "_U")})
    return _frame(data, units)


def _entry(fit: FitRecord, key: str, part: str) -> float:
    return float(getattr(fit, part)[fit.names.index(key)]) if key in fit.names else math.nan


def coefficient_table(fit: FitRecord, truth: dict[str, float] | None = None):
    """One fit's coefficients (index ``name``): value, std, U, unit, and the budget's parts.
    Their unit differs per row: ``attrs["row_units"]`` (name -> unit, the ``unit`` column)
    applies to every column in ``attrs["row_unit_columns"]``."""
    data = {"name": fit.names, "value": fit.value, "std": fit.std, "U": fit.U, "unit": fit.units}
    data.update({part: fit.budget[part] for part in BUDGET_PARTS if part in fit.budget})
    if truth:  # --sim: the fit's own truth (fits.csv's `true`), NaN where it gives none
        data["true"] = [float(truth.get(n, math.nan)) for n in fit.names]
    df = _frame(data, {"unit": ""}, "name")
    df.attrs["row_units"] = dict(zip(fit.names, fit.units))
    df.attrs["row_unit_columns"] = [k for k in data if k not in ("name", "unit")]
    return df


def covariance_frame(fit: FitRecord):
    """The covariance (SI) with the free coefficients' names as index and columns. Entry
    (i, j) is in unit(i) x unit(j): ``attrs["entry_units"][i][j]`` (pint parses it);
    ``attrs["row_units"]`` gives each coefficient's own unit (name -> unit)."""
    import pandas as pd

    names = fit.covariance_names if fit.covariance is not None else []
    df = pd.DataFrame(fit.covariance, index=names, columns=names) if names else pd.DataFrame()
    unit = dict(zip(fit.names, fit.units))
    df.attrs["units"] = {}
    df.attrs["row_units"] = {n: unit[n] for n in names}  # each coefficient's own unit
    df.attrs["entry_units"] = {i: {j: unit_product(unit[i], unit[j]) for j in names} for i in names}
    return df


def derived_frame(fit: FitRecord):
    """The derived quantities at the point's orbit frequencies (index ``orbit_hz``):
    c_eff_xx, c_eff_yy (N s/m), h_forward, h_backward (complex N/m), wfr (1), each with _std
    (H: _std_re, _std_im). The C_eff zero crossings are in attrs."""
    d = fit.derived or {}
    if "orbit_hz" not in d:
        return _frame({"orbit_hz": []}, {"orbit_hz": "Hz"}, "orbit_hz")
    data = {"orbit_hz": d["orbit_hz"]}
    units = {"orbit_hz": "Hz"}
    for name, unit in DERIVED_UNITS.items():
        if name in d:
            data[name], data[f"{name}_std"] = d[name], d.get(f"{name}_std")
            units[name] = units[f"{name}_std"] = unit
    for name in ("h_forward", "h_backward"):
        if f"{name}_re" in d:
            data[name] = np.asarray(d[f"{name}_re"]) + 1j * np.asarray(d[f"{name}_im"])
            std = np.asarray(d.get(f"{name}_std"), dtype=float)
            data[f"{name}_std_re"], data[f"{name}_std_im"] = std[0], std[1]
            units.update({name: "N/m", f"{name}_std_re": "N/m", f"{name}_std_im": "N/m"})
    df = _frame(data, units, "orbit_hz")
    df.attrs.update({k: d[k] for k in d if k.startswith("c_eff_zero")})
    df.attrs["covariance"] = d.get("covariance", "")
    return df


def waveforms_dataset(point, channels: list[str], channel_units: list[str]):
    """The point's averaged revolutions as an xarray Dataset: ``mean`` (block, channel, angle)
    with ``theta`` (rad, orbit angle after the trigger of each sample), ``dc``, ``phasor``
    (complex) and ``uncertainty`` (block, channel); per-channel units as attributes
    ``units_<channel>`` and the coordinate ``unit``."""
    import xarray as xr

    blocks = [f for f in point.frequencies if "mean" in f.waveform]
    if not blocks:
        return xr.Dataset()
    stack = lambda key: np.stack([b.waveform[key] for b in blocks])  # noqa: E731
    per_channel = {f"units_{c}": u for c, u in zip(channels, channel_units)}
    dims: tuple[str, ...] = ("block", "channel", "angle")
    data = {"mean": (dims, stack("mean"), {"description": "synchronous average over the revolutions", **per_channel})}
    for key, name, what in (
        ("dc", "dc", "mean value"),
        ("phasors", "phasor", "fundamental phasor, q = Re(q_bar exp(i theta))"),
        ("uncertainty", "uncertainty", "standard uncertainty of the phasor"),
    ):
        if all(key in b.waveform for b in blocks):
            data[name] = (dims[:2], stack(key), {"description": what, **per_channel})
    coords = {
        "block": [b.name for b in blocks],
        "channel": list(channels),
        "unit": ("channel", list(channel_units)),
        "orbit_hz": ("block", [b.orbit_hz for b in blocks], {"units": "Hz"}),
        "direction": ("block", [b.direction for b in blocks], {"units": "1", "description": "+1 forward, -1 backward"}),
        "n_records": ("block", [b.n_records for b in blocks], {"units": "1"}),
        "theta": (
            dims,
            slot_angle(stack("slots")),
            {"units": "rad", "description": "orbit angle after the trigger"},
        ),
    }
    return xr.Dataset(data, coords=coords, attrs={"point": point.index})
