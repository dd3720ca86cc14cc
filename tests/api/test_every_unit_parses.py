"""Every unit string a simulated run stores is read by pint (docs/storage.md, docs/api.md):
run.h5's and each point's results.h5's ``units``, ``units_<entry>``, ``A__units``, the logs'
``field_units`` and the identifications' ``units`` datasets, and the API frames' attrs. Text
has the unit "" (the command log's fields), never "1"; one quantity is spelled one way
(rigunits: damping is "N s/m" in the derived table as in the coefficients)."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest

import orbitrig
from rigunits import COEFFICIENT_UNITS, DAMPING, ONE, TEXT
from support.units import UREG


def _text(v: object) -> str:
    return v.decode("utf-8") if isinstance(v, bytes) else str(v)


def _unit_strings(path: Path) -> list[tuple[str, str]]:
    """(where, unit) of every unit string in the HDF5 file at `path`."""
    found: list[tuple[str, str]] = []

    def take(name: str, obj: h5py.HLObject) -> None:
        for key, value in obj.attrs.items():
            if key == "units" or key.startswith("units_") and key != "units_of_attributes" or key.endswith("__units"):
                found.append((f"{name}@{key}", _text(value)))
            elif key == "field_units":
                found.extend([(f"{name}@field_units[{i}]", _text(u)) for i, u in enumerate(value)])
        if isinstance(obj, h5py.Dataset) and name.rsplit("/", 1)[-1] == "units" and obj.dtype.kind == "S":
            found.extend((f"{name}[{i}]", _text(u)) for i, u in enumerate(np.atleast_1d(obj[()])))

    with h5py.File(path, "r") as f:
        take("/", f)
        f.visititems(take)
    return found


def _parse(where: str, unit: str) -> None:
    try:
        UREG.parse_units(unit)
    except Exception as err:  # pint raises several kinds  # noqa: BLE001
        pytest.fail(f"{where}: unit {unit!r} is not read by pint: {err}")


def test_every_stored_unit_parses(sim_run):
    files = [sim_run / "run.h5", *sorted(sim_run.glob("points/*/results.h5"))]
    assert len(files) >= 2
    for path in files:
        units = _unit_strings(path)
        assert len(units) > 100, (path, len(units))
        for where, unit in units:
            if unit != TEXT:
                _parse(f"{path.name}:{where}", unit)


def test_log_units_are_numbers_or_text(sim_run):
    with h5py.File(sim_run / "run.h5", "r") as f:
        can, drives, commands = f["logs/can"], f["logs/drives"], f["logs/commands"]
        can_units = dict(zip(can.attrs["fields"].astype(str), can.attrs["field_units"].astype(str)))
        assert can_units["p_supply"] == "Pa" and can_units["beta"] == ONE
        assert can_units["sensor_fault"] == can_units["pump_off"] == can_units["node_lost"] == ONE
        assert can.attrs["units_node_lost"] == ONE and can.attrs["units_flow"] == "m^3/s"
        drive_units = dict(zip(drives.attrs["fields"].astype(str), drives.attrs["field_units"].astype(str)))
        assert drive_units["spin_act"] == "rad/s"
        assert drive_units["spin_status"] == drive_units["orbit_fault"] == drive_units["spin_torque"] == ONE
        assert "spin_status: 1 (status word)" in drives.attrs["meaning"]  # what the number is, in words
        # the command log is text only: "" for every field, and no unit of the table as a whole
        assert "units" not in commands.attrs
        fields = list(commands.attrs["fields"].astype(str))
        assert list(commands.attrs["field_units"].astype(str)) == [TEXT] * len(fields)
        assert {k: commands.attrs[f"units_{k}"] for k in fields} == dict.fromkeys(fields, TEXT)
        events = f["logs/events"]
        assert events.attrs["units_t"] == "s" and events.attrs["units_message"] == TEXT


def test_api_frames_units_parse_and_damping_is_spelled_once(sim_run):
    run = orbitrig.open_run(sim_run)
    fit = run.fit(0, "piezo", "kcd11")
    frames = {
        "points": run.points,
        "table": run.table(0, "piezo"),
        "coefficients": run.coefficients,
        "fit.coefficients": fit.coefficients,
        "fit.covariance": fit.covariance,
        "fit.derived": fit.derived,
    }
    for name, df in frames.items():
        for col, unit in df.attrs["units"].items():
            if unit != TEXT:
                _parse(f"{name}.{col}", unit)
        for row, unit in df.attrs.get("row_units", {}).items():
            _parse(f"{name} row {row}", unit)
        for i, row in df.attrs.get("entry_units", {}).items():
            for j, unit in row.items():
                _parse(f"{name} ({i}, {j})", unit)
    derived = fit.derived.attrs["units"]
    assert derived["c_eff_xx"] == derived["c_eff_yy_std"] == DAMPING == COEFFICIENT_UNITS["C"]
    assert fit.coefficients.attrs["row_units"]["Cxx"] == derived["c_eff_xx"]
    assert derived["wfr"] == ONE
    assert run.coefficients.attrs["units"]["Cxy_U"] == DAMPING
