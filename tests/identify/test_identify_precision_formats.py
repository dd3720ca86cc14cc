"""`orbitrig identify --format csv` carries every number in full: each cell reads back as the very
double of the JSON (coefficients, standard errors, interval bounds, covariance, orbit_hz; the
force errors, which the JSON gives to 7 significant digits, in full);
the text tables round for reading and the help says so, not "every number in full"."""

from __future__ import annotations

import csv
import io
import json
import re

import pytest
from typer.testing import CliRunner

from orbitrig.cli import app
from support.paths import ROOT

TABLE = ROOT / "examples" / "orbit-tables" / "kcd11-constant.csv"


def _run(*args: str):
    res = CliRunner().invoke(app, ["identify", str(TABLE), "--model", "kcd11", *args], env={"COLUMNS": "200"})
    assert res.exit_code == 0, res.output
    return res


@pytest.fixture(scope="module")
def result() -> dict:
    return json.loads(_run("--json").stdout)


@pytest.fixture(scope="module")
def tables() -> dict[str, list[list[str]]]:
    """The CSV output's tables by the first word of their '# ' title."""
    out = {}
    for block in _run("--format", "csv").stdout.strip().split("\n\n"):
        title, body = block.split("\n", 1)
        out[title.split()[1]] = list(csv.reader(io.StringIO(body)))
    return out


def test_csv_coefficients_are_the_json_doubles(tables, result):
    head, *rows = tables["Coefficients"]
    assert head == ["coefficient", "value", "std error", "rel. std error [%]", "95 % interval", "unit"]
    assert [r[0] for r in rows] == list(result["coefficients"])
    for key, value, std, rel, interval, _ in rows:
        assert float(value) == result["coefficients"][key]
        assert float(std) == result["std_errors"][key]
        low, high = json.loads(interval)
        assert [low, high] == result["confidence_95"][key]
        assert float(rel) == 100 * result["std_errors"][key] / abs(result["coefficients"][key])
    kxx = result["coefficients"]["Kxx"]
    assert f"{kxx:.5g}" != repr(kxx) and rows[0][1] == repr(kxx)  # not the text table's 5 digits


def test_csv_covariance_and_forces_are_the_json_doubles(tables, result):
    head, *rows = tables["Covariance"]
    assert head == ["coefficient", "unit", *result["free"]]
    assert [[float(v) for v in r[2:]] for r in rows] == result["covariance"]
    head, *rows = tables["Reproduced"]
    keys = ("orbit_hz", "fx_amp_err_pct", "fx_phase_err_deg", "fy_amp_err_pct", "fy_phase_err_deg")
    assert [float(r[0]) for r in rows] == [f["orbit_hz"] for f in result["fit"]]
    # the JSON gives the errors to 7 significant digits (reduction.diagnostics); the CSV in full
    assert [[float(f"{float(v):.6e}") for v in r[1:]] for r in rows] == [
        [f[k] for k in keys[1:]] for f in result["fit"]
    ]
    assert any(len(v.replace("-", "").replace(".", "").lstrip("0")) > 7 for r in rows for v in r[1:])


def test_text_rounds_and_the_help_says_so(result):
    text = _run().stdout
    kxx = result["coefficients"]["Kxx"]
    shown = re.escape(f"{kxx * 1e-6:.5g}")  # in MN/m, as reduce's text
    assert re.search(rf"^Kxx\s+{shown}\s.*\sMN/m$", text, flags=re.M) and repr(kxx) not in text
    words = " ".join(CliRunner().invoke(app, ["identify", "--help"], env={"COLUMNS": "300"}).stdout.split())
    words = words.replace("│ ", "").replace(" │", "")
    assert "every number in full at any width" not in words
    assert "text: plain tables for reading, numbers rounded" in words and "K, C, D in MN/m, kN s/m, kg" in words
    assert "csv: the coefficient, force and covariance tables as CSV, in SI, every number in full" in words
