"""`orbitrig identify` on hand-made, awkward CSV files: every outcome is either the spec's
JSON (exit 0) or exit 2 with nothing on stdout and the line and column on stderr -
never a traceback."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from support.cli_helpers import orbitrig
from support.reduction_synthetic import frequencies, keys_of, orbit_table, truth
from orbitrig.cli import app
from orbitrig.store.orbit_table import write_orbit_table


TRUE = truth("kcd11", {"K": (0,), "C": (0,), "D": (0,)})


@pytest.fixture
def lines(tmp_path) -> list[str]:
    path = tmp_path / "good.csv"
    write_orbit_table(path, orbit_table(TRUE, frequencies(4)))
    return path.read_text().splitlines()


def _run(path: Path, *args: str):
    return CliRunner().invoke(app, ["identify", str(path), "--model", "kcd11", *args, "--json"])


def _ok(res) -> dict:
    assert res.exit_code == 0, res.stderr
    d = json.loads(res.stdout)
    for k, v in keys_of(TRUE).items():
        assert d["coefficients"][k] == pytest.approx(v, rel=1e-9)
    return d


def _refused(res, path: Path, line: int, column: str | None = None) -> str:
    assert res.exit_code == 2, res.output
    assert res.stdout == ""
    assert str(path) in res.stderr and f"line {line}" in res.stderr
    if column is not None:
        assert f"column '{column}'" in res.stderr
    return res.stderr


def test_bom_crlf_quotes_blank_lines_reordered_and_extra_columns(tmp_path, lines):
    header, rows = lines[0].split(","), [r.split(",") for r in lines[1:]]
    order = list(reversed(range(len(header))))
    out = ['"note",' + ",".join(f'"{header[k]}"' for k in order)]
    for r in rows:
        out += ['"a, quoted ""note"""' + "," + ",".join(f'" {r[k]} "' for k in order), ""]
    path = tmp_path / "nasty.csv"
    path.write_bytes(("\ufeff" + "\r\n".join(out) + "\r\n\r\n").encode("utf-8"))
    assert _ok(_run(path))["n_frequencies"] == len(rows)


def test_trailing_comma_on_data_rows_only_is_ignored(tmp_path, lines):
    path = tmp_path / "t.csv"
    path.write_text(lines[0] + "\n" + "\n".join(r + "," for r in lines[1:]) + "\n")
    _ok(_run(path))


def test_surplus_value_past_the_header_is_refused(tmp_path, lines):
    path = tmp_path / "t.csv"
    path.write_text("\n".join(lines[:3] + [lines[3] + ",7"] + lines[4:]) + "\n")
    _refused(_run(path), path, 4, "#11 (no header)")


@pytest.mark.parametrize("cell", ["1_000", "0x10", "1e", "--1", "1,5", "NaN", "-inf", "", "\u0661\u0662"])
def test_non_numeric_cells_name_line_and_column(tmp_path, lines, cell):
    header = lines[0].split(",")
    row = lines[2].split(",")
    row[header.index("fx_im")] = f'"{cell}"'
    path = tmp_path / "t.csv"
    path.write_text("\n".join(lines[:2] + [",".join(row)] + lines[3:]) + "\n")
    _refused(_run(path), path, 3, "fx_im")


def test_missing_column_is_named(tmp_path, lines):
    header = lines[0].split(",")
    j = header.index("y_re")
    path = tmp_path / "t.csv"
    path.write_text("\n".join(",".join(f for k, f in enumerate(r.split(",")) if k != j) for r in lines) + "\n")
    _refused(_run(path), path, 1, "y_re")


def test_one_frequency_only_names_the_reason_and_the_combinations(tmp_path, lines):
    path = tmp_path / "t.csv"
    path.write_text("\n".join(lines[:2]) + "\n")
    res = _run(path)
    assert res.exit_code == 2 and res.stdout == ""
    assert "too few orbit frequencies" in res.stderr and "at least 3" in res.stderr
    assert "cannot be separated" in res.stderr and "Kxx" in res.stderr


def test_over_long_field_is_a_malformed_table_not_a_traceback(tmp_path, lines):
    path = tmp_path / "t.csv"
    path.write_text("note," + lines[0] + "\n" + '"' + "a" * 200_000 + '",' + lines[1] + "\n")
    err = _refused(_run(path), path, 2)
    assert "field larger than field limit" in err


def test_file_that_is_not_utf8_names_line_and_field(tmp_path, lines):
    path = tmp_path / "t.csv"
    body = "\n".join([lines[0] + ",note"] + [r + ",ok" for r in lines[1:3]] + [lines[3] + ",caf\xe9"])
    path.write_bytes(body.encode("latin-1") + b"\n")
    err = _refused(_run(path), path, 4, "field 11")
    assert "not UTF-8" in err


def test_values_beyond_the_floating_point_range_exit_2(tmp_path, lines):
    """Finite but absurd values (e.g. forces in the wrong unit) must not end in a traceback."""
    header = lines[0].split(",")
    out = [lines[0]]
    for r in lines[1:]:
        f = r.split(",")
        for name in ("fx_re", "fx_im", "fy_re", "fy_im"):
            f[header.index(name)] = "1e308"
        out.append(",".join(f))
    path = tmp_path / "t.csv"
    path.write_text("\n".join(out) + "\n")
    for method in ("ols", "iv"):
        res = CliRunner().invoke(app, ["identify", str(path), "--model", "kcd11", "--method", method, "--json"])
        assert res.exit_code == 2 and res.stdout == "", res.output
        assert "floating-point range" in res.stderr


@pytest.mark.parametrize("method", ["ols", "wls", "tls", "iv"])
def test_u_columns_all_zero_name_the_columns_and_every_row(tmp_path, lines, method):
    path = tmp_path / "t.csv"
    rows = [r + ",0,0.0,0e0,0" for r in lines[1:]]
    path.write_text("\n".join([lines[0] + ",u_x,u_y,u_fx,u_fy", *rows]) + "\n")
    res = CliRunner().invoke(app, ["identify", str(path), "--model", "kcd11", "--method", method, "--json"])
    assert res.exit_code == 2 and res.stdout == "", res.output
    assert res.stderr == (
        f"orbitrig identify: error: every row (all {len(rows)}), columns 'u_x', 'u_y', 'u_fx', 'u_fy': all zero, "
        "so there is no noise to weight by; state the standard uncertainties, or leave the u_* columns out\n"
    )
    rows = [r + ",1e-9,1e-9,0.5,0.5" for r in lines[1:]]  # stated: the same table is identified
    path.write_text("\n".join([lines[0] + ",u_x,u_y,u_fx,u_fy", *rows]) + "\n")
    assert _ok(_run(path))["interval"] == "normal"


def test_real_process_never_prints_a_traceback(tmp_path, lines):
    path = tmp_path / "t.csv"
    path.write_text("note," + lines[0] + "\n" + '"' + "a" * 200_000 + '",' + lines[1] + "\n")
    res = orbitrig("identify", str(path), "--model", "kc7", "--json", timeout=60, columns=None)
    assert res.returncode == 2 and res.stdout == "" and "Traceback" not in res.stderr


def test_power_mnp_keys_carry_each_matrix_exponent(tmp_path):
    true = truth("kcd11", {"K": (0, 1), "C": (0, 2), "D": (0, 3)})
    path = tmp_path / "t.csv"
    write_orbit_table(path, orbit_table(true, frequencies(6)))
    res = CliRunner().invoke(app, ["identify", str(path), "--model", "kcd11", "--freq-dep", "power:1,2,3", "--json"])
    assert res.exit_code == 0, res.stderr
    d = json.loads(res.stdout)
    assert (d["freq_dep"], d["n_coefficients"], d["min_frequencies"]) == ("power:1,2,3", 22, 6)
    want = [
        f"{m}{e}{s}"
        for m, s in (("K", ""), ("K", "_1"), ("C", ""), ("C", "_2"), ("D", ""), ("D", "_3"))
        for e in ("xx", "xy", "yx", "yy")
    ]
    assert list(d["coefficients"]) == want and list(d["std_errors"]) == want
    assert d["coefficients"]["Dxy_3"] == d["coefficients"]["Dyx_3"]
    assert d["std_errors"]["Dxy"] == d["std_errors"]["Dyx"]
    for k, v in keys_of(true).items():
        assert d["coefficients"][k] == pytest.approx(v, rel=1e-9)


def test_repeated_extra_columns_are_ignored_a_repeated_spec_column_is_not(tmp_path, lines):
    path = tmp_path / "t.csv"
    path.write_text("\n".join([lines[0] + ",note,note,"] + [r + ",a,b," for r in lines[1:]]) + "\n")
    _ok(_run(path))
    path.write_text("\n".join([lines[0] + ",fx_re"] + [r + ",1" for r in lines[1:]]) + "\n")
    err = _refused(_run(path), path, 1, "fx_re")
    assert "appears twice" in err
