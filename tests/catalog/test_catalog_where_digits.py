"""`--where` on a number column takes a stored value within 1e-9 (relative) of the value written
as equal to it, on SQLite and on a real PostgreSQL server: 1.001 MPa is stored as
1000999.9999999999 Pa and 0.1 + 0.2 as 0.30000000000000004, and `recess_pressure = 1001000`
matched none of their rows before."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from orbitrig.catalog.rows import run_rows
from orbitrig.cli import app
from orbitrig.store.reader import read_run
from rigunits import MPA

N_FITS = 8  # per point: four models on each load measuring system


@pytest.fixture
def noisy(catalog, catalog_run):
    rows = run_rows(read_run(catalog_run))
    for row in rows:
        if row["point"] == 0:
            row["recess_pressure"] = 1.001 * MPA
        else:
            row["static_eccentricity"] = 0.1 + 0.2
    assert 1.001 * MPA != 1001000 and 0.1 + 0.2 != 0.3
    catalog.add(rows)
    return catalog


@pytest.mark.parametrize(
    "where, points",
    [
        ("recess_pressure = 1001000", [0]),
        ("recess_pressure == 1.001e6", [0]),
        ("recess_pressure != 1001000", [1]),
        ("static_eccentricity = 0.3", [1]),
        ("static_eccentricity <= 0.3", [0, 1]),
        ("static_eccentricity < 0.3", [0]),
        ("static_eccentricity >= 0.3", [1]),
        ("static_eccentricity > 0.3", []),
        ("static_eccentricity = 0.3000001", []),
        ("static_eccentricity = 0", [0]),
    ],
)
def test_a_number_equals_the_value_written_to_nine_digits(noisy, where, points):
    rows = noisy.rows(where)
    assert sorted({r["point"] for r in rows}) == points
    assert len(rows) == N_FITS * len(points)


def test_catalog_list_finds_the_rows_of_1_001_mpa(noisy):
    res = CliRunner().invoke(
        app, ["catalog", "list", "--db", noisy.url, "--where", "recess_pressure = 1001000", "--columns", "point"]
    )
    assert res.exit_code == 0, res.output
    assert res.stdout.split() == ["point"] + ["0"] * N_FITS
