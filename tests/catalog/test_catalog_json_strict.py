"""The catalog's JSON is strict JSON (RFC 8259, what jq and a browser's JSON.parse read): a fit
whose standard error and U could not be estimated (stored as null) gives null in
coefficients_json, never NaN, in the database and in `catalog export --format json`, on SQLite
and on a real PostgreSQL server."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from orbitrig.catalog.rows import run_rows
from orbitrig.cli import app
from orbitrig.store.reader import read_run


def _strict(text: str):
    def refuse(constant: str):
        raise ValueError(f"not JSON: {constant}")

    return json.loads(text, parse_constant=refuse)


def test_an_unknown_std_and_u_are_null_not_nan(catalog_run, catalog):
    run = read_run(catalog_run)
    ident = run.points[0].identification("piezo", "kcd11", "none")
    ident.result["std_errors"]["Kxx"] = None  # as identify stores a std it could not estimate
    ident.result.pop("expanded_uncertainty", None)
    ident.result.pop("uncertainty", None)
    catalog.add(run_rows(run, run.points[:1]))
    row = next(r for r in catalog.rows() if (r["lms"], r["model"], r["freq_dep"]) == ("piezo", "kcd11", "none"))
    stored = _strict(row["coefficients_json"])
    assert stored["std"]["Kxx"] is None and stored["U"]["Kxx"] is None and row["Kxx_U"] is None
    assert stored["U"]["Kyy"] == pytest.approx(row["Kyy_U"], rel=1e-12)
    out = CliRunner().invoke(app, ["catalog", "export", "--format", "json", "--db", catalog.url])
    assert out.exit_code == 0, out.output
    exported = _strict(out.stdout)
    mine = next(
        r for r in exported if (r["point"], r["lms"], r["model"], r["freq_dep"]) == (0, "piezo", "kcd11", "none")
    )
    assert mine["coefficients_json"]["std"]["Kxx"] is None
    assert mine["coefficients_json"]["values"]["Kxx"] == pytest.approx(row["Kxx"], rel=1e-12)


def test_a_row_catalogued_with_nan_exports_as_null(catalog_run, catalog):
    rows = run_rows(read_run(catalog_run))[:1]
    rows[0]["coefficients_json"] = '{"values": {"Kxx": 1.0}, "U": {"Kxx": NaN}, "std": {}, "k": 2.0}'
    catalog.add(rows)
    out = CliRunner().invoke(app, ["catalog", "export", "--format", "json", "--db", catalog.url])
    assert out.exit_code == 0, out.output
    assert _strict(out.stdout)[0]["coefficients_json"]["U"] == {"Kxx": None}
