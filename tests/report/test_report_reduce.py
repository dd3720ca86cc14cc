"""`orbitrig reduce DIR`: identify again from stored phasors, without the rig."""

from __future__ import annotations

import csv
import hashlib
import json
import re
import shutil

import h5py

import numpy as np
import pytest
from support.report_synthetic import C_TRUE, K_TRUE, write_synthetic_run
from support.rounded_cells import with_error
from typer.testing import CliRunner

from orbitrig.cli import app
from orbitrig.analysis.reduce import csv_path, reduce_run, write_csv
from orbitrig.store.reader import read_run


def _digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _within(value, truth, pct):
    """Every entry within pct % of the largest entry of its matrix (the issue's criterion)."""
    return np.all(np.abs(value - truth) <= pct / 100 * np.abs(truth).max())


def test_reduce_recovers_known_coefficients(synthetic_run):
    rows = reduce_run(read_run(synthetic_run), "kcd11")
    piezo = [r for r in rows if r.lms == "piezo"]
    assert [r.point.index for r in piezo] == [0, 1]  # the incomplete point is skipped
    for r in piezo:
        K, C, D = r.identification.matrices(100.0)
        assert _within(K, K_TRUE, 1.0) and _within(C, C_TRUE, 2.0)


def test_reduce_matches_the_stored_identification(synthetic_run):
    run = read_run(synthetic_run)
    compared = 0
    for point in run.complete_points:
        for stored in point.identifications:
            if not stored.ok:
                continue
            rows = reduce_run(run, stored.model, stored.freq_dep, stored.method, lms_names=(stored.lms,))
            (again,) = [r for r in rows if r.point.index == point.index]
            for key, value in stored.result["coefficients"].items():
                assert again.identification.coefficients[key] == pytest.approx(value, rel=1e-9, abs=1e-9)
            compared += 1
    assert compared >= 12


def test_reduce_csv_has_coefficients_std_and_truth(synthetic_run, tmp_path):
    run = read_run(synthetic_run)
    rows = reduce_run(run, "kc7")
    path = write_csv(tmp_path / "out.csv", rows, run.sim)
    with path.open() as fh:
        table = list(csv.DictReader(fh))
    assert [(int(r["point"]), r["lms"]) for r in table] == [(0, "piezo"), (0, "strain"), (1, "piezo"), (1, "strain")]
    first = table[0]
    assert first["model"] == "kc7" and first["freq_dep"] == "none" and first["error"] == ""
    assert float(first["Kxx [N/m]"]) == pytest.approx(rows[0].identification.coefficients["Kxx"])
    assert float(first["Cxy_std [N s/m]"]) > 0
    assert float(first["true_Kxy [N/m]"]) == pytest.approx(K_TRUE[0, 1])
    assert float(first["recess_pressure_mpa"]) == pytest.approx(0.4826)
    assert not any(c.startswith("Dxx") for c in first)  # kc7 has no inertia


def test_cli_reduce_writes_csv_and_leaves_the_run_alone(synthetic_run):
    before = _digest(synthetic_run / "run.h5")
    result = CliRunner().invoke(app, ["reduce", str(synthetic_run), "--model", "kcd11", "--freq-dep", "power:1"])
    assert result.exit_code == 0, result.output
    assert "Kxx [MN/m]" in result.stdout and "0001" in result.stdout
    out = csv_path(synthetic_run, "kcd11", "power:1", "ols")
    assert out.name == "reduce_kcd11_power_1_ols.csv" and out.is_file()
    with out.open() as fh:
        assert len(list(csv.DictReader(fh))) == 4
    assert _digest(synthetic_run / "run.h5") == before


def test_cli_reduce_help_states_the_csv_columns(synthetic_run, tmp_path):
    """The help's account of the CSV is true: coefficients.csv's columns but KEY_U; not_determined by
    the identification's own statistical U = k x std (as `reduce --json` gives it)."""
    words = " ".join(CliRunner().invoke(app, ["reduce", "--help"]).stdout.replace("│", " ").split())
    assert "the columns of coefficients.csv except the expanded uncertainties KEY_U" in words
    assert (
        "not_determined names the coefficients whose statistical expanded uncertainty k x KEY_std (k = 2 with u_*) "
        "exceeds their magnitude" in words
    )
    run = shutil.copytree(synthetic_run, tmp_path / "run")
    assert CliRunner().invoke(app, ["reduce", str(run), "--model", "kcd11"]).exit_code == 0
    with csv_path(run, "kcd11", "none", "ols").open() as fh:
        reduced = list(csv.DictReader(fh))
    with (run / "coefficients.csv").open() as fh:
        stored = next(csv.reader(fh))
    columns = list(reduced[0])
    assert not [c for c in columns if c.split(" [")[0].endswith("_U")]
    assert set(columns) <= set(stored) and "Kxx_U [N/m]" in stored and "Kxx [N/m]" in columns
    without_u = [c for c in stored if not c.split(" [")[0].endswith("_U")]
    assert [c for c in without_u if c in columns] == columns  # the same order
    own = json.loads(CliRunner().invoke(app, ["reduce", str(run), "--model", "kcd11", "--json"]).stdout)
    assert [r["not_determined"] for r in reduced] == [" ".join(o["not_determined"]) for o in own["results"]]
    assert any(r["not_determined"] for r in reduced)  # D of kcd11 on the synthetic run: not determined


def test_cli_reduce_json(synthetic_run):
    result = CliRunner().invoke(app, ["reduce", str(synthetic_run), "--model", "kc8", "--json"])
    assert result.exit_code == 0, result.output
    out = json.loads(result.stdout)
    assert out["status"] == "stopped" and len(out["results"]) == 4
    r0 = out["results"][0]
    assert r0["point"] == 0 and r0["lms"] == "piezo" and r0["model"] == "kc8"
    assert r0["coefficients"]["Kxx"] == pytest.approx(K_TRUE[0, 0], rel=0.01)
    assert set(r0["std_errors"]) == set(r0["coefficients"])


def test_cli_reduce_refuses_unidentifiable_model(synthetic_run):
    # kcd12 poly:8: 11 powers of Omega per real part of Z, the run has 10 orbit frequencies
    result = CliRunner().invoke(app, ["reduce", str(synthetic_run), "--model", "kcd12", "--freq-dep", "poly:8"])
    assert result.exit_code == 2
    assert result.stdout == ""
    assert "refused" in result.stderr and "kcd12" in result.stderr
    assert not csv_path(synthetic_run, "kcd12", "poly:8", "ols").exists()


@pytest.mark.parametrize(
    "args, message",
    [
        (["--model", "kcd99"], "kcd99"),
        (["--model", "kcd11", "--freq-dep", "wiggly"], "wiggly"),
        (["--model", "kcd11", "--method", "magic"], "magic"),
    ],
)
def test_cli_reduce_bad_option(synthetic_run, args, message):
    result = CliRunner().invoke(app, ["reduce", str(synthetic_run), *args])
    assert result.exit_code == 2 and message in result.stderr and result.stdout == ""


def test_cli_reduce_bad_directory(tmp_path):
    missing = CliRunner().invoke(app, ["reduce", str(tmp_path / "nope"), "--model", "kcd11"])
    assert missing.exit_code == 2 and "no such directory" in missing.stderr
    empty = CliRunner().invoke(app, ["reduce", str(tmp_path), "--model", "kcd11"])
    assert empty.exit_code == 2 and "no run.h5" in empty.stderr and str(tmp_path) in empty.stderr


def test_cli_reduce_partial_refusal_keeps_the_other_points(synthetic_run, tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    shutil.copy(synthetic_run / "run.h5", run / "run.h5")
    with h5py.File(run / "run.h5", "r+") as f:  # point 1 keeps 2 of its 20 rows: too few for kcd11
        for lms in ("piezo", "strain"):
            t = f[f"points/0001/table/{lms}"]
            for name in ("orbit", "x", "y", "fx", "fy", "gamma2", "n_records", "u"):
                data = t[name][:2]
                del t[name]
                t[name] = data
    result = CliRunner().invoke(app, ["reduce", str(run), "--model", "kcd11"])
    assert result.exit_code == 0, result.output
    assert "refused at point 0001 piezo, 0001 strain" in result.stderr
    rows = list(csv.DictReader(csv_path(run, "kcd11", "none", "ols").open()))
    assert [(r["point"], r["lms"], bool(r["error"]), bool(r["Kxx [N/m]"])) for r in rows] == [
        ("0", "piezo", False, True),
        ("0", "strain", False, True),
        ("1", "piezo", True, False),
        ("1", "strain", True, False),
    ]


def test_cli_reduce_names_a_damaged_point_and_reduces_the_others(tmp_path):
    """As `export` and `report`: a point whose piece is damaged is named, exit 1, the rest written."""
    run = write_synthetic_run(tmp_path / "run", n_points=3, incomplete=0)
    piece = run / "points" / "0001" / "02_fwd.h5"
    with piece.open("r+b") as fh:
        fh.truncate(100)
    result = CliRunner().invoke(app, ["reduce", str(run), "--model", "kc8"])
    assert result.exit_code == 1, result.output
    assert "error: point 0001 skipped: 02_fwd.h5 is damaged" in result.stderr
    assert "2 complete point(s)" in " ".join(result.stdout.split()) and "written:" in result.stdout  # heading folded
    rows = list(csv.DictReader(csv_path(run, "kc8", "none", "ols").open()))
    assert sorted({r["point"] for r in rows}) == ["0", "2"]
    bad = CliRunner().invoke(app, ["reduce", str(run), "--model", "kcd99"])
    assert bad.exit_code == 2 and "kcd99" in bad.stderr  # a bad option stays a usage error
    ok = write_synthetic_run(tmp_path / "ok", n_points=1)
    undamaged = CliRunner().invoke(app, ["reduce", str(ok), "--model", "kc8"])
    assert undamaged.exit_code == 0 and "point 0001 not included: never completed" in undamaged.stderr
    assert "error:" not in undamaged.stderr


def test_cli_reduce_power_auto_shows_the_chosen_exponent(synthetic_run):
    result = CliRunner().invoke(app, ["reduce", str(synthetic_run), "--model", "kc7", "--freq-dep", "power:auto"])
    assert result.exit_code == 0, result.output
    blocks = "\n".join(result.stdout.splitlines()[1:-1]).split("\n\n")  # a wide table: column blocks
    legend = " ".join(blocks[-1].split())  # then what the columns are
    assert "M = the exponent power:auto chose" in legend and "constant terms (Omega^0)" in legend
    assert legend.startswith("K, C, D: value \u00b1 its standard error") and "resid = RMS of measured minus" in legend
    header, *rows = blocks[-2].splitlines()  # the table's last block ends with M, after the key columns
    assert header.split()[-1] == "M"
    data = [r.split() for r in rows if r.split()[1] in ("piezo", "strain")]
    assert len(data) == 4 and all(r[-1] in {"1", "2", "3", "4"} for r in data)


SI_UNITS = {"K": "N/m", "C": "N s/m", "D": "kg"}


def test_cli_reduce_csv_has_every_number_in_full_si(synthetic_run, tmp_path):
    """`--format csv` prints the table in SI with every number in full: each cell reads back as the
    very double of `--json` (coefficients, residual) and of the written file's true_* columns;
    the text table rounds (MN/m, kN s/m, kg to 4 significant digits) and the help says which is which."""
    run = shutil.copytree(synthetic_run, tmp_path / "run")
    result = CliRunner().invoke(app, ["reduce", str(run), "--model", "kcd11", "--format", "csv"])
    assert result.exit_code == 0, result.output
    rows = list(csv.DictReader(result.stdout.splitlines()))
    own = json.loads(CliRunner().invoke(app, ["reduce", str(run), "--model", "kcd11", "--json"]).stdout)["results"]
    with csv_path(run, "kcd11", "none", "ols").open(newline="") as fh:
        written = list(csv.DictReader(fh))
    assert (
        list(rows[0])[:3] == ["point", "lms", "Kxx [N/m]"] and "Dyy [kg]" in rows[0] and "residual_rms [N]" in rows[0]
    )
    assert [r["lms"] for r in rows] == [lms for o in own for lms in (o["lms"], f"true ({o['lms']})")]
    for fit, true, o, w in zip(rows[::2], rows[1::2], own, written):
        assert fit["point"] == true["point"] == w["point"] == str(o["point"])  # the index, as every CSV file
        for key, value in o["coefficients"].items():
            if "_" not in key:  # the constant terms
                assert float(fit[f"{key} [{SI_UNITS[key[0]]}]"]) == value, key
        assert float(fit["residual_rms [N]"]) == o["residual_rms"]  # the name of the file written and the JSON
        assert "residual_rms [N]" in w
        for column, cell in true.items():
            if column not in ("point", "lms") and cell:
                assert float(cell) == float(w[f"true_{column}"]), column
    kxx, kxx_std = own[0]["coefficients"]["Kxx"], own[0]["std_errors"]["Kxx"]
    assert rows[0]["Kxx [N/m]"] == repr(kxx) and rows[0]["Kxx_std [N/m]"] == repr(kxx_std)
    assert list(rows[0])[3] == "Kxx_std [N/m]" and rows[1]["Kxx_std [N/m]"] == ""  # the true row has none
    text = CliRunner().invoke(app, ["reduce", str(run), "--model", "kcd11"], env={"COLUMNS": "300"}).stdout
    assert "Kxx [MN/m]" in text and with_error(kxx * 1e-6, kxx_std * 1e-6) in text and repr(kxx) not in text
    words = " ".join(CliRunner().invoke(app, ["reduce", "--help"], env={"COLUMNS": "300"}).stdout.split())
    words = words.replace("│ ", "").replace(" │", "")
    assert "csv: the same table in SI (N/m, N s/m, kg), each term followed by its _std, every number in full" in words


def _text_rows(stdout: str) -> dict[tuple[str, str], dict[str, str]]:
    """(point, lms) -> {column: cell} of `reduce`'s text table printed in one block (cells apart
    by two or more spaces)."""
    lines = [line for line in stdout.splitlines() if line.startswith(("point ", "0"))]
    head = re.split(r"\s{2,}", lines[0])
    return {(c[0], c[1]): dict(zip(head, c)) for c in (re.split(r"\s{2,}", line) for line in lines[1:])}


def test_cli_reduce_text_shows_each_term_with_its_standard_error(synthetic_run, tmp_path):
    """A referee reads every term beside its standard error, in MN/m, kN s/m and kg: the error to
    2 significant digits, the value (and the true row's) to the same decimal, the legend says so."""
    run = shutil.copytree(synthetic_run, tmp_path / "run")
    text = CliRunner().invoke(app, ["reduce", str(run), "--model", "kcd11"], env={"COLUMNS": "400"}).stdout
    own = json.loads(CliRunner().invoke(app, ["reduce", str(run), "--model", "kcd11", "--json"]).stdout)["results"]
    shown = _text_rows(text)
    scales = {"K": ("MN/m", 1e-6), "C": ("kN s/m", 1e-3), "D": ("kg", 1.0)}
    checked = 0
    for o in own:
        fit, true = shown[(f"{o['point']:04d}", o["lms"])], shown[(f"{o['point']:04d}", f"true ({o['lms']})")]
        for key, value in o["coefficients"].items():
            unit, scale = scales[key[0]]
            cell = with_error(value * scale, o["std_errors"][key] * scale)
            assert fit[f"{key} [{unit}]"] == cell, (key, fit[f"{key} [{unit}]"], cell)
            decimals = len(cell.split(" ")[0].partition(".")[2])
            assert len(true[f"{key} [{unit}]"].partition(".")[2]) == decimals, key
            checked += 1
    assert checked == 4 * 12  # 2 points x 2 LMS x Kxx..Dyy (Dxy and Dyx one coefficient, both shown)
    assert shown[("0000", "piezo")]["Kxx [MN/m]"].count(".") == 2  # e.g. '33.022 ± 0.073'
    words = " ".join(text.split())
    assert (
        "K, C, D: value \u00b1 its standard error (k = 1, statistical: the fit's, no calibration; the CSV's _std)"
        in words
    )
    assert "to 2 significant digits of the error and the value to the same decimal; units in the header" in words


def test_a_value_is_rounded_to_the_decimal_of_its_uncertainty():
    from orbitrig.analysis.rounding import with_uncertainty

    assert with_uncertainty(33.0216, 0.07334) == "33.022 \u00b1 0.073"
    assert with_uncertainty(12.3, 0.0996) == "12.30 \u00b1 0.10"  # the error rounds up a decade
    assert with_uncertainty(-0.001, 0.1234) == "0.00 \u00b1 0.12"  # no '-0.00'
    assert with_uncertainty(123456.0, 1234.0) == "123500 \u00b1 1200"
    assert with_uncertainty(2.5, None) == with_uncertainty(2.5, float("nan")) == "2.5 \u00b1 -"
