"""Terminal output that loses nothing: `identify`, `reduce` and the sweep's closing table at
80 columns and piped (no cell cut, no line wider than the terminal unless one cell is), and
the same content as CSV and JSON (`--format`). The text is read from `orbitrig` processes (piped,
COLUMNS set or unset); CSV and JSON, which take no width, from the command run in this process."""

from __future__ import annotations

import csv
import io
import json
import os
import re
import subprocess

import numpy as np
import pytest

from orbitrig.cli.plain_table import OutputFormat, PlainTable

from support.cli_helpers import orbitrig_cmd, orbitrig_here
from support.paths import ROOT
from support.rounded_cells import with_error

TABLE = ROOT / "examples" / "orbit-tables" / "kcd11-constant.csv"


def run(*args: str, columns: str | None) -> subprocess.CompletedProcess:
    """`orbitrig ARGS` piped (not a terminal), with COLUMNS set or unset."""
    env = {k: v for k, v in os.environ.items() if k != "COLUMNS"}
    if columns is not None:
        env["COLUMNS"] = columns
    return subprocess.run(
        orbitrig_cmd(*args),
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        stdin=subprocess.DEVNULL,
    )


def here(*args: str) -> subprocess.CompletedProcess:
    """`orbitrig ARGS` run in this process (output not a terminal), 80 columns: for CSV and JSON."""
    return orbitrig_here(*args, columns=80)


def test_a_table_wider_than_the_terminal_is_split_never_cut():
    t = PlainTable(title="t")
    t.add_column("key")
    for i in range(6):
        t.add_column(f"column {i}", justify="right")
    t.add_row("a", *(f"{-9.0571234e6 * (i + 1):.6e}" for i in range(6)))
    text = t.text(40)
    assert "..." not in text and "\u2026" not in text
    assert all(len(line) <= 40 for line in text.splitlines())
    for i in range(6):
        assert f"{-9.0571234e6 * (i + 1):.6e}" in text
    assert text.count("\nkey") == 3  # two columns per block, the key column heading each
    assert list(csv.reader(io.StringIO(t.csv())))[1][1] == f"{-9.0571234e6:.6e}"
    t.add_row("b", "x" * 100)  # one cell wider than the terminal: written whole, never cut
    assert "x" * 100 in t.text(40)


@pytest.mark.parametrize("columns", ["80", None])
def test_identify_at_80_columns_and_piped_keeps_every_number(columns):
    res = run("identify", str(TABLE), "--model", "kcd11", columns=columns)
    assert res.returncode == 0, res.stderr
    text = res.stdout
    assert "..." not in text and "\u2026" not in text
    assert max(len(line) for line in text.splitlines()) <= 80  # piped: 80 columns too
    result = json.loads(here("identify", str(TABLE), "--model", "kcd11", "--json").stdout)
    for key, value in result["coefficients"].items():  # in the units reduce's text shows: MN/m, kN s/m, kg
        unit, k = {"K": ("MN/m", 1e-6), "C": ("kN s/m", 1e-3), "D": ("kg", 1.0)}[key[0]]
        lo, hi = result["confidence_95"][key]
        row = rf"^{key}\s+{re.escape(f'{value * k:.5g}')}\s.*{re.escape(f'[{lo * k:.4g}, {hi * k:.4g}]')}\s+{unit}$"
        assert re.search(row, text, flags=re.M), key


def test_identify_formats_csv_and_json():
    as_csv = here("identify", str(TABLE), "--model", "kc8", "--format", "csv")
    assert as_csv.returncode == 0, as_csv.stderr
    blocks = as_csv.stdout.split("\n\n")
    assert blocks[0].startswith("# Coefficients") and blocks[1].startswith("# Reproduced vs measured")
    rows = list(csv.DictReader(io.StringIO(blocks[0].split("\n", 1)[1])))
    as_json = here("identify", str(TABLE), "--model", "kc8", "--format", "json")
    result = json.loads(as_json.stdout)
    assert [r["coefficient"] for r in rows] == list(result["coefficients"])
    assert all(float(r["value"]) == pytest.approx(result["coefficients"][r["coefficient"]], rel=1e-4) for r in rows)
    assert as_json.stdout == here("identify", str(TABLE), "--model", "kc8", "--json").stdout


def _covariance_shown(text: str) -> dict[tuple[str, str], str]:
    """The covariance table of identify's text output: (row, column) -> cell, its column blocks joined."""
    part = text.split("\nCovariance of the free coefficients", 1)[1]
    cells: dict[tuple[str, str], str] = {}
    for block in part.split("\n\n"):
        lines = [ln for ln in block.splitlines() if ln.startswith(("coefficient ", "K", "C", "D"))]
        header = re.split(r"\s{2,}", lines[0].strip())
        assert header[:2] == ["coefficient", "unit"], header
        for line in lines[1:]:
            row = re.split(r"\s{2,}", line.strip())
            cells |= {(row[0], col): cell for col, cell in zip(header[2:], row[2:], strict=True)}
            cells[(row[0], "unit")] = row[1]
    return cells


@pytest.mark.parametrize("columns", ["80", None])
def test_identify_text_shows_the_whole_covariance_with_units(columns):
    res = run("identify", str(TABLE), "--model", "kcd11", columns=columns)
    assert res.returncode == 0, res.stderr
    assert max(len(line) for line in res.stdout.splitlines()) <= 80
    shown = _covariance_shown(res.stdout)
    result = json.loads(here("identify", str(TABLE), "--model", "kcd11", "--json").stdout)
    free, cov = result["free"], result["covariance"]
    assert len(free) == 11 and {(a, "unit") for a in free} | {(a, b) for a in free for b in free} == set(shown)
    scale = {"K": 1e-6, "C": 1e-3, "D": 1.0}  # the coefficients' text units: MN/m, kN s/m, kg
    for i, a in enumerate(free):
        assert shown[(a, "unit")] == {"K": "MN/m", "C": "kN s/m", "D": "kg"}[a[0]]
        for j, b in enumerate(free):
            assert shown[(a, b)] == f"{cov[i][j] * scale[a[0]] * scale[b[0]]:.4g}", (a, b)


def test_identify_csv_has_the_covariance_matrix():
    as_csv = here("identify", str(TABLE), "--model", "kcd11", "--format", "csv")
    assert as_csv.returncode == 0, as_csv.stderr
    blocks = as_csv.stdout.split("\n\n")
    assert [b.split(" ", 2)[1] for b in blocks] == ["Coefficients", "Reproduced", "Covariance"]
    rows = list(csv.reader(io.StringIO(blocks[2].split("\n", 1)[1])))
    result = json.loads(here("identify", str(TABLE), "--model", "kcd11", "--json").stdout)
    assert rows[0] == ["coefficient", "unit", *result["free"]]
    assert [r[0] for r in rows[1:]] == result["free"] and rows[4][1] == "N/m" and rows[-1][1] == "kg"
    matrix = [[float(v) for v in r[2:]] for r in rows[1:]]
    np.testing.assert_allclose(matrix, result["covariance"], rtol=5e-4)


def _cells(text: str) -> set[str]:
    """The table cells shown that hold a number (runs of text between wide gaps; note sentences,
    which are folded at 80 columns, left out)."""
    return {w for w in re.split(r"\s{2,}|\n", text) if re.search(r"\d", w) and len(w) < 40}


@pytest.mark.parametrize("n_points", [2, 6])  # full tables per point; one summary row per point
def test_closing_table_at_80_columns_shows_what_a_wide_terminal_shows(tmp_path, capsys, monkeypatch, n_points):
    from support.report_synthetic import write_synthetic_run

    from orbitrig.cli.sweep_summary import print_coefficients

    run_dir = write_synthetic_run(tmp_path / "run", n_points=n_points, incomplete=0)
    monkeypatch.setenv("COLUMNS", "400")
    print_coefficients(run_dir)
    wide = capsys.readouterr().out
    monkeypatch.setenv("COLUMNS", "80")
    print_coefficients(run_dir)
    narrow = capsys.readouterr().out
    assert max(len(line) for line in narrow.splitlines()) <= 80
    table_cells = _cells("\n".join(ln for ln in wide.splitlines() if not ln.startswith(("point 0", "K / C", "|dZ|"))))
    assert table_cells and table_cells <= _cells(narrow)
    print_coefficients(run_dir, OutputFormat.JSON)
    data = json.loads(capsys.readouterr().out)
    if n_points == 6:  # the point by its index, as coefficients.csv names it (the text: 0000 ..)
        with (run_dir / "coefficients.csv").open(newline="") as fh:
            in_file = list(dict.fromkeys(r["point"] for r in csv.DictReader(fh)))
        assert [r["point"] for r in data["tables"][0]["rows"]] == in_file == [str(i) for i in range(6)]
        print_coefficients(run_dir, OutputFormat.CSV)
        table = [ln for ln in capsys.readouterr().out.splitlines() if not ln.startswith("#")]  # no title, notes
        assert [r["point"] for r in csv.DictReader(table)] == in_file
        assert re.findall(r"^0\d{3}(?=\s)", wide, flags=re.M) == [f"{i:04d}" for i in range(6)]
    else:
        assert [t["title"].split()[1] for t in data["tables"]] == ["0000", "0001"]
        assert {r["coef"] for r in data["tables"][0]["rows"]} >= {"Kxx", "Cyy", "Dxy"}
    assert any("expanded uncertainty" in n or "worst normalised" in n for n in data["notes"])


def test_reduce_formats(tmp_path):
    from support.report_synthetic import write_synthetic_run

    run_dir = write_synthetic_run(tmp_path / "run", n_points=1, incomplete=0)
    text = run("reduce", str(run_dir), "--model", "kcd11", columns="80")
    assert text.returncode == 0, text.stderr
    assert max(len(line) for line in text.stdout.splitlines() if not line.startswith("written")) <= 80  # a path
    assert "kcd11 none (ols) from the stored orbit tables of" in text.stdout  # the heading, folded
    assert {"Kxx [MN/m]", "Cxx [kN s/m]", "Dxx [kg]"} <= set(re.split(r"\s{2,}|\n", text.stdout))  # as identify's
    rows = list(csv.DictReader(io.StringIO(here("reduce", str(run_dir), "--model", "kcd11", "--format", "csv").stdout)))
    assert [(r["point"], r["lms"]) for r in rows] == [
        ("0", "piezo"),
        ("0", "true (piezo)"),
        ("0", "strain"),
        ("0", "true (strain)"),
    ]  # the point's index, as in the file written beside (and coefficients.csv)
    with (run_dir / "reduce_kcd11_none_ols.csv").open(newline="") as fh:
        assert [(r["point"], r["lms"]) for r in csv.DictReader(fh)] == [("0", "piezo"), ("0", "strain")]
    for r in rows[::2]:  # the CSV in SI and in full, the text table the same numbers rounded to their errors
        for key, unit, scale in (("Kxx", "N/m", 1e-6), ("Dyy", "kg", 1.0)):
            shown = with_error(float(r[f"{key} [{unit}]"]) * scale, float(r[f"{key}_std [{unit}]"]) * scale)
            assert re.search(rf"\s{re.escape(shown)}(\s|$)", text.stdout), shown
