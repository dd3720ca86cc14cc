"""The catalog states its units where a program reads them: the table `fits_units` (every
column of `fits`), the CSV export's headers, and each row's coefficients_json; pint parses
each, and they agree with one another and with the run's own units."""

from __future__ import annotations

import csv
import io
import json
import math

import pint
import pytest
from sqlalchemy import select

from orbitrig.catalog.errors import CatalogError
from orbitrig.catalog.render import ExportFormat, render
from orbitrig.catalog.rows import run_rows
from orbitrig.catalog.schema import ROW_COLUMNS, fits_units
from orbitrig.catalog.store import Catalog
from orbitrig.store.reader import read_run

UREG = pint.UnitRegistry()


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
