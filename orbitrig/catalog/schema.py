"""The catalog's one table, ``fits``: one row per (run, point, load system, model,
frequency dependence, method), its columns and their units (docs/catalog.md)."""

from __future__ import annotations

from typing import Any

from sqlalchemy import Boolean, Column, Float, Integer, MetaData, String, Table, Text, UniqueConstraint

from orbitrig.catalog.rows import COEFFICIENTS, UNITS

metadata = MetaData()

#: the unique key: re-adding a row with the same key replaces it
KEY = ("run_id", "point", "lms", "model", "freq_dep", "method")

_TEXT = (
    "run_path",
    "run_status",
    "created",
    "matrix_name",
    "software_version",
    "operator",
    "rig_id",
    "host",
    "calibration_record",
    "calibration_record_sha256",
    "started",
    "ended",
    "sim_scenario",
    "sim_scenario_sha256",
    "label",
    "orbit_hz",
    "error",
    "u_basis",
    "adequacy_verdict",
    "not_determined",
    "coefficients_json",
)
_FLOAT = (
    "bearing_radius",
    "bearing_clearance",
    "spin",
    "spin_rpm",
    "recess_pressure",
    "pressure_ratio",
    "static_eccentricity",
    "dynamic_eccentricity",
    "chi2",
    "p_value",
)

#: column -> unit, for the columns that have one (the rest are counts, ratios or text);
#: the CSV export's headers carry it ("Kxx [N/m]", "orbit_hz [Hz]": a JSON list of Hz)
COLUMN_UNITS = {
    "spin": "rad/s",
    "spin_rpm": "rpm",
    "recess_pressure": "Pa",
    "orbit_hz": "Hz",
    "bearing_radius": "m",
    "bearing_clearance": "m",
    **{c: UNITS[c[0]] for c in COEFFICIENTS},
    **{f"{c}_U": UNITS[c[0]] for c in COEFFICIENTS},
}


def _columns() -> list[Column[Any]]:
    cols: list[Column[Any]] = [
        Column("id", Integer, primary_key=True, autoincrement=True),
        Column("run_id", String(200), nullable=False),
        Column("point", Integer, nullable=False),
        Column("lms", String(40), nullable=False),
        Column("model", String(40), nullable=False),
        Column("freq_dep", String(80), nullable=False),
        Column("method", String(40), nullable=False),
        Column("ok", Boolean, nullable=False),
        Column("sim", Boolean),
        Column("sim_seed", Integer),
        Column("n_frequencies", Integer),
        Column("adequacy_supported", Boolean),
    ]
    cols += [Column(name, Text) for name in _TEXT]
    cols += [Column(name, Float) for name in _FLOAT]
    for name in COEFFICIENTS:
        cols += [Column(name, Float), Column(f"{name}_U", Float)]
    return cols


fits = Table("fits", metadata, *_columns(), UniqueConstraint(*KEY, name="fits_key"))

#: the columns a row carries (all but the surrogate id)
ROW_COLUMNS = tuple(c.name for c in fits.columns if c.name != "id")

#: the unit of every column of ``fits`` in a form pint parses: COLUMN_UNITS, "1" for the other
#: numbers and flags (ratios, counts, chi2), "" for text
UNIT_OF = {
    c.name: COLUMN_UNITS.get(c.name, "" if isinstance(c.type, (String, Text)) else "1")
    for c in fits.columns
    if c.name != "id"
}

#: table ``fits_units``: each column of ``fits`` and its unit (UNIT_OF), for readers of the database
fits_units = Table(
    "fits_units",
    metadata,
    Column("column_name", String(80), primary_key=True),
    Column("unit", String(80), nullable=False),
)
