"""`compare --model/--freq-dep` are fit names compared as they are: a name holding a quote, a space
or a word of the filter's grammar ('or') said there is no such fit, with the fits the catalog has;
it gave a grammar error about a --where filter the user never wrote."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from orbitrig.catalog.rows import run_rows
from orbitrig.catalog.store import Catalog
from orbitrig.cli import app
from orbitrig.store.reader import read_run


@pytest.mark.parametrize("model", ["kc'7", 'kc"7', "kc 7", "or"])
def test_an_unusual_model_name_is_no_fit_not_a_filter_error(catalog_run, tmp_path, model):
    Catalog(f"sqlite:///{tmp_path / 'catalog.sqlite'}").add(run_rows(read_run(catalog_run)))
    res = CliRunner().invoke(app, ["compare", "--runs", str(tmp_path), "--model", model, "--out", str(tmp_path / "f")])
    assert res.exit_code == 2 and "--where" not in res.output
    assert res.output.startswith(
        f"orbitrig compare: error: no catalog rows for piezo {model} none ols; the catalog's fits: "
    )
    assert "piezo kc7 none ols" in res.output


def test_a_name_with_both_quotes_is_refused_naming_the_option(catalog_run, tmp_path):
    Catalog(f"sqlite:///{tmp_path / 'catalog.sqlite'}").add(run_rows(read_run(catalog_run)))
    res = CliRunner().invoke(app, ["compare", "--runs", str(tmp_path), "--freq-dep", "a'b\"c"])
    assert res.exit_code == 2
    assert (
        res.output.strip()
        == "orbitrig compare: error: --freq-dep 'a\\'b\"c': a name holding both quote characters is no fit's name"
    )


def test_the_fit_named_plainly_is_still_drawn(catalog_run, tmp_path):
    Catalog(f"sqlite:///{tmp_path / 'catalog.sqlite'}").add(run_rows(read_run(catalog_run)))
    res = CliRunner().invoke(app, ["compare", "--runs", str(tmp_path), "--model", "kc7", "--out", str(tmp_path / "f")])
    assert res.exit_code == 0 and (tmp_path / "f" / "compare.png").is_file()
