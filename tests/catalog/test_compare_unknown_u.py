"""`compare` draws a value whose U is not known (NULL: a fit stored without it) without a bar and
names it on standard error: it drew a bar of length 0 with its caps, a U of 0 to the eye."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from orbitrig.catalog.compare import Variable
from orbitrig.catalog.compare_plot import compare_figure
from orbitrig.catalog.rows import run_rows
from orbitrig.catalog.store import Catalog
from orbitrig.cli import app
from orbitrig.store.reader import read_run


def _rows(catalog_run):
    rows = [
        r
        for r in run_rows(read_run(catalog_run))
        if (r["lms"], r["model"], r["freq_dep"]) == ("piezo", "kcd11", "none")
    ]
    assert [r["point"] for r in rows] == [0, 1]
    rows[0]["Kxx_U"] = None
    return rows


def test_no_bar_where_u_is_not_known(catalog_run):
    rows = _rows(catalog_run)
    fig = compare_figure(rows, Variable.STATIC_ECCENTRICITY, ["Kxx"], title="t")
    (container,) = fig.axes[0].containers
    (bars,) = container.lines[2]
    drawn = [seg for seg in bars.get_segments() if len(seg) and not np.isnan(seg).any()]
    assert len(drawn) == 1  # point 0: no bar
    (x, low), (_, high) = drawn[0]
    assert x == pytest.approx(0.15) and high - low == pytest.approx(2 * rows[1]["Kxx_U"] * 1e-6, rel=1e-9)  # MN/m


def test_compare_names_the_points_without_u(catalog_run, tmp_path):
    rows = _rows(catalog_run)
    Catalog(f"sqlite:///{tmp_path / 'catalog.sqlite'}").add(rows)
    res = CliRunner().invoke(
        app, ["compare", "--runs", str(tmp_path), "--coefficients", "Kxx,Kyy", "--out", str(tmp_path / "fig")]
    )
    assert res.exit_code == 0, res.output
    assert f"compare: Kxx has no U at {rows[0]['run_id']} point 0: drawn without a bar" in res.stderr
    assert "Kyy has no U" not in res.stderr
