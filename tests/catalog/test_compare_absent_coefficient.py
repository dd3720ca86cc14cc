"""`compare --coefficients` naming a coefficient the compared model has not (kc7 has no D) is
refused, exit 2, naming it and what the rows give: it drew an empty panel and exited 0."""

from __future__ import annotations

from typer.testing import CliRunner

from orbitrig.catalog.rows import run_rows
from orbitrig.catalog.store import Catalog
from orbitrig.cli import app
from orbitrig.store.reader import read_run


def test_a_coefficient_no_row_gives_is_refused_naming_it(catalog_run, tmp_path):
    Catalog(f"sqlite:///{tmp_path / 'catalog.sqlite'}").add(run_rows(read_run(catalog_run)))
    base = ["compare", "--runs", str(tmp_path), "--model", "kc7", "--out", str(tmp_path / "fig")]
    res = CliRunner().invoke(app, [*base, "--coefficients", "Kxx,Dxx"])
    assert res.exit_code == 2 and not (tmp_path / "fig").exists()
    assert res.output.strip() == (
        "orbitrig compare: error: --coefficients Dxx: no catalog row of piezo kc7 none ols gives it (the model has none); "
        "its rows give Kxx, Kxy, Kyx, Kyy, Cxx, Cxy, Cyx, Cyy"
    )
    res = CliRunner().invoke(app, [*base, "--coefficients", "Kxx,Cyy"])  # what kc7 has: drawn
    assert res.exit_code == 0 and (tmp_path / "fig" / "compare.png").is_file()
