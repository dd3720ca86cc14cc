"""compare's u is U / k with the fit's own coverage factor k, not U / 2: a fit whose
covariance comes from its residual (a small table without u_*) has k = Student's t at
95.45 % with its dof (2.87 at dof 4), and the catalog stores that k beside U."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from scipy.stats import chi2, t
from typer.testing import CliRunner

from orbitrig.catalog.compare import UBasis, coverage, repeatability
from orbitrig.catalog.rows import _fit_columns
from orbitrig.catalog.store import Catalog
from orbitrig.cli import app
from orbitrig.load_systems import LoadSystem
from orbitrig.store.stored_run import StoredIdentification
from support.campaign import campaign_rows
from support.paths import ROOT


@pytest.fixture(scope="module")
def residual_fit(tmp_path_factory) -> dict:
    """`identify --json` of kc8 on three rows of a table without u_*: dof 4, student_t."""
    lines = (ROOT / "examples" / "orbit-tables" / "kc8-coherence.csv").read_text().splitlines()
    table = tmp_path_factory.mktemp("small") / "small.csv"
    table.write_text("\n".join(lines[:4]) + "\n")
    done = CliRunner().invoke(app, ["identify", str(table), "--model", "kc8", "--json"])
    assert done.exit_code == 0, done.output
    result = json.loads(done.output)
    assert (result["interval"], result["dof"]) == ("student_t", 4)
    return result


def _row(result: dict, run: int, kxx: float, record: str) -> dict:
    """A catalog row of run `run` (the campaign's conditions) holding `result` with Kxx = kxx."""
    fit = {**result, "coefficients": {**result["coefficients"], "Kxx": kxx}}
    row = campaign_rows(n_runs=run + 1)[run * 5]
    row.update(_fit_columns(StoredIdentification(LoadSystem("piezo"), "kc8", "none", fit, None)))
    row.update(calibration_record_sha256=record)
    return row


def test_compare_takes_u_as_U_over_the_stored_k(residual_fit, tmp_path: Path):
    k = float(t.ppf(1 - (1 - 0.9545) / 2, 4))  # 2.87, not 2
    std = residual_fit["std_errors"]["Kxx"]
    x1 = residual_fit["coefficients"]["Kxx"]
    x2 = x1 + 3.0 * std
    catalog = Catalog(f"sqlite:///{tmp_path / 'catalog.sqlite'}")
    catalog.add([_row(residual_fit, 0, x1, "ab" * 32), _row(residual_fit, 1, x2, "cd" * 32)])
    rows = catalog.rows()
    catalog.close()
    assert len(rows) == 2
    for row in rows:
        assert row["Kxx_U"] == pytest.approx(k * std, rel=1e-9)
        assert coverage(row) == pytest.approx(k, rel=1e-9)
        assert row["u_basis"] == "statistical"
    rep = repeatability(rows, "Kxx")  # two calibration records: u = U / k = std
    assert rep.basis == UBasis.EXPANDED and rep.dof == 1
    assert rep.chi2 == pytest.approx((x2 - x1) ** 2 / (2 * std**2), rel=1e-6)  # 4.5; U/2 gave 4.5 (2/k)^2 = 2.2
    assert rep.p_value == pytest.approx(chi2.sf(4.5, 1), rel=1e-6)
    assert rep.text().endswith(", u = U/k")


def test_a_row_stored_without_k_keeps_k_2():
    row = campaign_rows(n_runs=1)[0]
    row["coefficients_json"] = json.dumps({"values": {}, "U": {}, "std": {}})
    assert coverage(row) == 2.0


def test_the_figure_says_its_bars_are_U_with_the_fits_k(residual_fit):
    """The figure names what its bars are, for a reader of the figure alone (a journal's): U with
    the k of its rows' fits, 2 for a sweep's, Student's t for a fit without u_*; it said nothing."""
    from orbitrig.catalog.compare import Variable
    from orbitrig.catalog.compare_plot import compare_figure

    sweep_rows = campaign_rows(n_runs=1)
    drawn = compare_figure(sweep_rows, Variable.STATIC_ECCENTRICITY, ["Kxx"], title="T")
    assert drawn.get_suptitle() == "T\nbars: expanded uncertainty U (k = 2)"
    mixed = [_row(residual_fit, 1, residual_fit["coefficients"]["Kxx"], "cd" * 32), *sweep_rows]
    drawn = compare_figure(mixed, Variable.STATIC_ECCENTRICITY, ["Kxx"], title="T")
    assert drawn.get_suptitle() == "T\nbars: expanded uncertainty U (each fit's k: 2, 2.87)"
