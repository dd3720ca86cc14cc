"""`orbitrig identify --format csv` says the unit of every number, as the JSON's ``units`` does:
a header field's unit in brackets (the orbit table's convention), else its row's ``unit``
column; pint parses every unit given, and the force table's columns are the contract's
``fit`` keys (docs/orbit-table.md, docs/protocols/README.md)."""

from __future__ import annotations

import csv
import io
import json
import re

from typer.testing import CliRunner

from orbitrig.cli import app
from support.paths import ROOT
from support.units import UREG

BRACKETED = re.compile(r"^(?P<name>.+) \[(?P<unit>[^\]]+)\]$")


def _identify(table: str, *args: str) -> str:
    res = CliRunner().invoke(app, ["identify", str(ROOT / "examples" / "orbit-tables" / table), *args])
    assert res.exit_code == 0, res.output
    return res.stdout


def _tables(text: str) -> dict[str, list[list[str]]]:
    out = {}
    for block in text.strip().split("\n\n"):
        title, body = block.split("\n", 1)
        out[title.split()[1]] = list(csv.reader(io.StringIO(body)))
    return out


def test_every_csv_number_has_a_unit_pint_parses() -> None:
    args = ("--model", "kcd11", "--freq-dep", "poly:2")
    tables = _tables(_identify("kcd11-poly2.csv", *args, "--format", "csv"))
    result = json.loads(_identify("kcd11-poly2.csv", *args, "--json"))
    coef, forces, cov = tables["Coefficients"], tables["Reproduced"], tables["Covariance"]
    assert [BRACKETED.match(h)["name"] for h in forces[0]] == list(result["fit"][0])  # the contract's keys
    units = {m["unit"] for table in tables.values() for h in table[0] if (m := BRACKETED.match(h))}
    assert units == {"Hz", "%", "deg"}
    unit_col = {r[0]: r[coef[0].index("unit")] for r in coef[1:]}
    assert unit_col == result["units"] and {r[0]: r[1] for r in cov[1:]} == {
        k: result["units"][k] for k in result["free"]
    }
    units |= set(unit_col.values())
    assert {"N/m (rad/s)^-1", "N s/m (rad/s)^-2", "kg (rad/s)^-2"} <= units  # the orders' units too
    dims = {u: UREG.parse_units(u).dimensionality for u in units}
    assert dims["Hz"] == UREG.parse_units("1/s").dimensionality and UREG.Quantity(1, "%").to("").m == 0.01
    assert dims["N s/m (rad/s)^-2"] == (UREG.newton / UREG.meter * UREG.second**3).dimensionality  # rad is 1
    assert UREG.Quantity(180, "deg").to("rad").m == UREG.Quantity(3.141592653589793, "rad").m


def test_csv_cells_are_numbers_or_empty() -> None:
    """A program reads every cell of a number column as a float: no '%' inside a cell, no '-'."""
    coef = _tables(_identify("kcd11-constant.csv", "--model", "kcd11", "--format", "csv"))["Coefficients"]
    for row in coef[1:]:
        for cell in row[1:3] + row[3:4]:
            float(cell)
        low, high = json.loads(row[4])
        assert low < float(row[1]) < high
