"""The catalog states its units where a program reads them: the table `fits_units` (every
column of `fits`), the CSV export's headers, and each row's coefficients_json; pint parses
each, and they agree with one another and with the run's own units."""

from __future__ import annotations

import csv
import io
import json
import math

import pytest
from sqlalchemy import select

from orbitrig.catalog.errors import CatalogError
from orbitrig.catalog.render import ExportFormat, render
from orbitrig.catalog.rows import run_rows
from orbitrig.catalog.schema import ROW_COLUMNS, fits_units
from orbitrig.catalog.store import Catalog, Dialect
from orbitrig.store.reader import read_run
from support.units import UREG


def _units(catalog) -> dict[str, str]:
    with catalog.engine.connect() as conn:
        return dict(conn.execute(select(fits_units.c.column_name, fits_units.c.unit)).all())


def test_every_column_has_its_unit_in_the_database(catalog, catalog_run):
    catalog.add(run_rows(read_run(catalog_run)))
    units = _units(catalog)
    assert set(units) == set(ROW_COLUMNS)
    assert (units["Kxx"], units["Cyy_U"], units["Dxy"]) == ("N/m", "N s/m", "kg")
    assert (units["spin"], units["spin_rpm"], units["recess_pressure"], units["orbit_hz"]) == (
        "rad/s",
        "rpm",
        "Pa",
        "Hz",
    )
    assert (units["bearing_clearance"], units["pressure_ratio"], units["chi2"], units["label"]) == ("m", "1", "1", "")
    assert UREG.Quantity(1.0, units["spin_rpm"]).to("rad/s").magnitude == pytest.approx(2 * math.pi / 60, rel=1e-15)
    for unit in filter(None, units.values()):
        UREG.parse_units(unit)  # raises on a unit pint cannot read

    # the CSV headers carry the same units: "Kxx [N/m]"; a bare name is text, a number of unit 1, or spin_rpm
    header = next(csv.reader(io.StringIO(render(catalog.rows(), ExportFormat.CSV).decode())))
    bracketed = {h.split(" [")[0]: h.split(" [")[1].rstrip("]") for h in header if " [" in h}
    assert bracketed == {c: u for c, u in units.items() if u not in ("", "1", "rpm")}

    # coefficients_json: every coefficient of the fit with its unit, as the run states it
    run = read_run(catalog_run)
    for row in catalog.rows("model = kcd11 and freq_dep = power:1 and lms = piezo"):
        stored = json.loads(row["coefficients_json"])
        result = run.points[row["point"]].identification("piezo", "kcd11", "power:1").result
        assert stored["units"] == result["units"] and stored["units"]["Kxx_1"] == "N/m (rad/s)^-1"
        assert set(stored["units"]) == set(stored["values"])


def test_a_catalog_of_this_version_opens_read_only(catalog_run, tmp_path):
    """Its units are written once: `list` and `compare` open it without writing (an SQLite
    file opened read-only, mode=ro); a wrong unit stored is put right when it can be written."""
    path = tmp_path / "c.sqlite"
    writable = Catalog(f"sqlite:///{path}")
    writable.add(run_rows(read_run(catalog_run)))
    with writable.engine.begin() as conn:
        conn.execute(fits_units.update().where(fits_units.c.column_name == "Kxx").values(unit="N"))
    writable.close()
    with pytest.raises(CatalogError, match="readonly"):  # it would have to write
        Catalog(f"sqlite:///file:{path}?mode=ro&uri=true", create=False)
    Catalog(f"sqlite:///{path}").close()  # puts it right
    read_only = Catalog(f"sqlite:///file:{path}?mode=ro&uri=true", create=False)
    try:
        assert _units(read_only)["Kxx"] == "N/m" and len(read_only.rows()) == 2 * 8
    finally:
        read_only.close()


def _unit_rows(catalog) -> dict[str, tuple[str, str]]:
    """column -> (unit, the version of its row): PostgreSQL's xmin, which any write of the
    row changes (an upsert of the same unit too); SQLite's rowid."""
    version = "xmin::text" if catalog.dialect is Dialect.POSTGRESQL else "CAST(rowid AS TEXT)"
    with catalog.engine.connect() as conn:
        found = conn.exec_driver_sql(f"SELECT column_name, unit, {version} FROM fits_units").all()
    return {name: (unit, v) for name, unit, v in found}


def test_a_newer_versions_units_stand(catalog, catalog_run, tmp_path):
    """A catalog a newer version wrote (a column this version does not know, a unit spelt
    otherwise, a unit it left out): opening it here adds the missing unit of a column of
    this version and changes nothing else, then writes nothing at all on the next open."""
    catalog.add(run_rows(read_run(catalog_run)))
    url = catalog.url
    with catalog.engine.begin() as conn:  # as the newer version left it
        conn.exec_driver_sql("ALTER TABLE fits ADD COLUMN journal_length FLOAT")
        conn.execute(fits_units.insert(), [{"column_name": "journal_length", "unit": "m"}])
        conn.execute(fits_units.update().where(fits_units.c.column_name == "Cxx").values(unit="N*s/m"))
        conn.execute(fits_units.delete().where(fits_units.c.column_name == "label"))
    newer = _unit_rows(catalog)
    catalog.close()
    try:
        older = Catalog(url, create=False)
        units = _unit_rows(older)
        assert units["label"][0] == "" and {c: units[c] for c in newer} == newer  # nothing rewritten
        assert (units["journal_length"], units["Cxx"]) == (newer["journal_length"], ("N*s/m", newer["Cxx"][1]))
        assert len(older.rows()) == 2 * 8
        older.close()
        again = Catalog(url, create=False)
        assert _unit_rows(again) == units
        again.close()
        if catalog.dialect is Dialect.SQLITE:  # the proof that nothing is written: a read-only file opens
            Catalog(f"sqlite:///file:{url.removeprefix('sqlite:///')}?mode=ro&uri=true", create=False).close()
    finally:
        with catalog.engine.begin() as conn:  # leave the session's server with this version's tables
            conn.exec_driver_sql("DROP TABLE fits_units")
            conn.exec_driver_sql("DROP TABLE fits")
        Catalog(url).close()


def test_a_nan_the_database_keeps_is_an_empty_cell_and_null(catalog, catalog_run):
    """PostgreSQL keeps a NaN in a float column (SQLite stores NULL): the CSV export wrote 'nan',
    where the docs say an empty cell is NULL; both exports say 'not known' one way."""
    from sqlalchemy import text

    catalog.add(run_rows(read_run(catalog_run)))
    with catalog.engine.begin() as conn:
        conn.execute(text('UPDATE fits SET "Kxx_U" = :v WHERE point = 0'), {"v": float("nan")})
    rows = catalog.rows()
    table = list(csv.DictReader(io.StringIO(render(rows, ExportFormat.CSV).decode())))
    cells = {(r["point"], r["model"], r["lms"], r["freq_dep"], r["method"]): r["Kxx_U [N/m]"] for r in table}
    assert {v for k, v in cells.items() if k[0] == "0"} == {""}
    assert all(v and math.isfinite(float(v)) for k, v in cells.items() if k[0] != "0" and v)
    objects = json.loads(render(rows, ExportFormat.JSON))
    assert {o["Kxx_U"] for o in objects if o["point"] == 0} == {None}
