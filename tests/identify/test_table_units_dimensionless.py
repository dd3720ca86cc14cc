"""Units in an orbit table's header (docs/orbit-table.md, "The CSV"): a dimensionless column may
state `[1]` or `[-]` (the shared contract writes "-"); a misspelt optional column is ignored,
and when that leaves a set of four incomplete the refusal names it as the likely cause, in the
words the documentation quotes."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from typer.testing import CliRunner

from orbitrig.cli import app
from orbitrig.errors import TableError
from orbitrig.store.orbit_table import read_orbit_table, write_orbit_table
from support.paths import ROOT
from support.reduction_synthetic import frequencies, orbit_table, truth

DIMENSIONLESS = ("gamma2_xfx", "gamma2_yfx", "gamma2_xfy", "gamma2_yfy", "n_records", "direction")


@pytest.fixture
def with_units(tmp_path):
    """A kc8 table with coherences, n_records and u_*, every header field with its unit ("[1]"
    for the dimensionless ones), as `orbitrig export --format csv` writes it."""
    clean = orbit_table(truth("kc8", {"K": (0,), "C": (0,)}), frequencies(4))
    rng = np.random.default_rng(3)
    table = type(clean)(
        clean.spin,
        clean.orbit,
        clean.x,
        clean.y,
        clean.fx,
        clean.fy,
        rng.uniform(0.9, 1.0, (clean.n, 4)),
        np.arange(40, 40 + clean.n),
        np.tile([1e-8, 2e-8, 0.5, 0.7], (clean.n, 1)),
    )
    path = tmp_path / "units.csv"
    write_orbit_table(path, table, units=True)
    assert all(f"{c} [1]" in path.read_text().splitlines()[0] for c in DIMENSIONLESS)
    return path


def _with_header(path, old: str, new: str, name: str):
    head, rest = path.read_text().split("\n", 1)
    assert old in head
    out = path.with_name(name)
    out.write_text(head.replace(old, new) + "\n" + rest)
    return out


def test_dash_is_read_as_the_dimensionless_unit(with_units):
    dash = _with_header(with_units, "[1]", "[-]", "dash.csv")
    assert "gamma2_xfx [-]" in dash.read_text() and "[1]" not in dash.read_text().splitlines()[0]
    one, other = read_orbit_table(with_units), read_orbit_table(dash)
    for name in ("orbit", "x", "y", "fx", "fy", "gamma2", "n_records", "u"):
        np.testing.assert_array_equal(getattr(other, name), getattr(one, name))
    assert other.gamma2.shape == (8, 4) and other.n_records[0] == 40
    runs = [CliRunner().invoke(app, ["identify", str(p), "--model", "kc8", "--json"]) for p in (with_units, dash)]
    assert [r.exit_code for r in runs] == [0, 0], runs[1].output
    assert json.loads(runs[1].stdout)["coefficients"] == json.loads(runs[0].stdout)["coefficients"]


@pytest.mark.parametrize(
    "old, new, column, expected",
    [
        ("gamma2_xfx [1]", "gamma2_xfx [%]", "gamma2_xfx [%]", "the unit of gamma2_xfx is '1' or '-', not '%'"),
        ("u_fx [N]", "u_fx [-]", "u_fx [-]", "the unit of u_fx is 'N', not '-'"),
        ("orbit_hz [Hz]", "orbit_hz [1]", "orbit_hz [1]", "the unit of orbit_hz is 'Hz', not '1'"),
    ],
)
def test_a_wrong_unit_is_still_refused(with_units, old, new, column, expected):
    bad = _with_header(with_units, old, new, "bad.csv")
    with pytest.raises(TableError) as info:
        read_orbit_table(bad)
    assert (info.value.line, info.value.column) == (1, column) and expected in str(info.value)


def test_misspelt_u_column_is_named_as_the_likely_cause_as_documented(with_units):
    bad = _with_header(with_units, "u_fx [N]", "u_fX [N]", "misspelt.csv")
    res = CliRunner().invoke(app, ["identify", str(bad), "--model", "kc8", "--json"])
    assert res.exit_code == 2 and res.stdout == ""
    message = res.stderr.strip()
    assert message.startswith(f"orbitrig identify: error: malformed table: {bad}, line 1, column 'u_fx': ")
    assert "column 'u_fX' in the header looks like it" in message and "rename it u_fx" in message
    doc = " ".join((ROOT / "docs" / "orbit-table.md").read_text(encoding="utf-8").split())
    quoted = re.search(r"names the misspelt column as the likely cause: `column 'u_fx': ([^`]*)`", doc)
    assert quoted and message.endswith(quoted.group(1))  # the documentation quotes the real message
    assert "is refused (exit status 2" in doc and "three of the four `u_*`" in doc
