"""`orbitrig identify` against the spec: JSON on stdout, exit 2 with reasons on stderr."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from support.cli_helpers import orbitrig
from support.identify_keys import keys
from support.reduction_synthetic import frequencies, keys_of, orbit_table, truth
from orbitrig.cli import app
from orbitrig.store.orbit_table import write_orbit_table


TRUE = truth("kcd11", {"K": (0,), "C": (0,), "D": (0,)})


@pytest.fixture
def runner():
    return CliRunner()


@pytest.fixture
def table_csv(tmp_path):
    path = tmp_path / "table.csv"
    write_orbit_table(path, orbit_table(TRUE, frequencies(5), gamma2=[0.99, 0.98, 0.97, 0.995]))
    return path


def test_json_output_follows_the_spec(runner, table_csv):
    res = runner.invoke(app, ["identify", str(table_csv), "--model", "kcd11", "--json"])
    assert res.exit_code == 0, res.stderr
    d = json.loads(res.stdout)
    assert list(d) == keys(has_uncertainty=False)
    assert (d["model"], d["freq_dep"], d["method"]) == ("kcd11", "none", "ols")
    assert (d["n_coefficients"], d["min_frequencies"], d["n_frequencies"]) == (11, 3, 10)
    for k, v in keys_of(TRUE).items():
        assert d["coefficients"][k] == pytest.approx(v, rel=1e-9)
    assert d["coefficients"]["Dxy"] == d["coefficients"]["Dyx"]
    assert set(d["std_errors"]) == set(d["coefficients"])
    assert len(d["fit"]) == 10 and d["fit"][0]["orbit_hz"] == pytest.approx(frequencies(5)[0])
    assert res.stderr == ""


@pytest.mark.parametrize("method", ["wls", "tls", "iv"])
@pytest.mark.parametrize("solver", ["svd", "lu"])
def test_methods_and_solvers(runner, table_csv, method, solver):
    res = runner.invoke(
        app, ["identify", str(table_csv), "--model", "kcd11", "--method", method, "--solver", solver, "--json"]
    )
    assert res.exit_code == 0, res.stderr
    d = json.loads(res.stdout)
    assert d["method"] == method
    assert d["coefficients"]["Kxx"] == pytest.approx(keys_of(TRUE)["Kxx"], rel=1e-9)


def test_power_auto_reports_the_exponent(runner, tmp_path):
    true = truth("kc7", {"K": (0, 2), "C": (0, 2)})
    path = tmp_path / "t.csv"
    write_orbit_table(path, orbit_table(true, frequencies(6)))
    res = runner.invoke(app, ["identify", str(path), "--model", "kc7", "--freq-dep", "power:auto", "--json"])
    assert res.exit_code == 0, res.stderr
    d = json.loads(res.stdout)
    assert d["freq_dep"] == "power:auto" and d["exponent"] == 2 and d["n_coefficients"] == 14
    assert d["coefficients"]["Cxy_2"] == d["coefficients"]["Cyx_2"]


def test_readable_table_without_json(runner, table_csv):
    res = runner.invoke(app, ["identify", str(table_csv), "--model", "kc8"])
    assert res.exit_code == 0, res.stderr
    assert "Kxx" in res.stdout and "N s/m" in res.stdout and "condition number" in res.stdout
    assert "fx_amp_err_pct [%]" in res.stdout and "orbit_hz [Hz]" in res.stdout
    # 5 frequencies, each in both whirl directions: 10 rows, not "10 orbit frequencies"
    words = " ".join(res.stdout.split())
    assert "8 coefficients from 10 rows (5 distinct orbit frequencies; minimum 2 rows)" in words


def test_rank_deficient_model_exit_2_nothing_on_stdout(runner, tmp_path):
    path = tmp_path / "fwd.csv"
    true = truth("kc8", {"K": (0, 1), "C": (0, 1)})
    write_orbit_table(path, orbit_table(true, frequencies(8), ("forward",)))
    res = runner.invoke(app, ["identify", str(path), "--model", "kc8", "--freq-dep", "power:1", "--json"])
    assert res.exit_code == 2
    assert res.stdout == ""
    assert "Kxx_1 - Cxy" in res.stderr and "forward plus backward whirl" in res.stderr


def test_paper_33_coefficient_model_fits_29_with_the_absorbed_order_noted(runner, tmp_path):
    path = tmp_path / "t.csv"
    write_orbit_table(path, orbit_table(TRUE, frequencies(10)))
    res = runner.invoke(app, ["identify", str(path), "--model", "kcd11", "--freq-dep", "poly:2", "--json"])
    assert res.exit_code == 0, res.stderr
    d = json.loads(res.stdout)
    assert d["n_coefficients"] == 29 and d["min_frequencies"] == 8 and len(d["free"]) == 29
    assert "Kxx_2" not in d["coefficients"] and "Kxx_1" in d["coefficients"]
    assert any("K order 2" in n for n in d["notes"])


def test_forward_only_fixed_ellipse_power_1_exit_2(runner, tmp_path):
    path = tmp_path / "t.csv"
    write_orbit_table(path, orbit_table(TRUE, frequencies(10), ((5e-6, 4.9e-6, 0.3),)))
    res = runner.invoke(app, ["identify", str(path), "--model", "kc8", "--freq-dep", "power:1", "--json"])
    assert res.exit_code == 2 and res.stdout == ""
    assert "Kxx_1 - Cxy" in res.stderr and "backward-whirl" in res.stderr


def test_too_few_frequencies_exit_2(runner, tmp_path):
    path = tmp_path / "t.csv"
    write_orbit_table(path, orbit_table(TRUE, frequencies(2), ("forward",)))
    res = runner.invoke(app, ["identify", str(path), "--model", "kcd11", "--json"])
    assert res.exit_code == 2 and res.stdout == ""
    assert "too few orbit frequencies" in res.stderr and "at least 3" in res.stderr


def test_wls_without_coherence_exit_2(runner, tmp_path):
    path = tmp_path / "t.csv"
    write_orbit_table(path, orbit_table(TRUE, frequencies(4)))
    res = runner.invoke(app, ["identify", str(path), "--model", "kcd11", "--method", "wls", "--json"])
    assert res.exit_code == 2 and res.stdout == "" and "gamma2" in res.stderr


def test_unknown_model_exit_2(runner, table_csv):
    res = runner.invoke(app, ["identify", str(table_csv), "--model", "kcd13", "--json"])
    assert res.exit_code == 2 and res.stdout == "" and "unknown model" in res.stderr


GOOD_HEADER = "spin_rpm,orbit_hz,x_re,x_im,y_re,y_im,fx_re,fx_im,fy_re,fy_im"


@pytest.mark.parametrize(
    "text, line, column",
    [
        (GOOD_HEADER + "\n1000,5,1e-6,0,0,-1e-6,1,2,3,4\n1000,6,1e-6,0,0,abc,1,2,3,4\n", 3, "y_im"),
        (GOOD_HEADER.replace("fy_im", "fyim") + "\n1000,5,1e-6,0,0,-1e-6,1,2,3,4\n", 1, "fy_im"),
        (GOOD_HEADER + "\n1000,5,1e-6,0,0,-1e-6,1,2,3,4\n1000,0,1e-6,0,0,-1e-6,1,2,3,4\n", 3, "orbit_hz"),
        (GOOD_HEADER + "\n1000,5,1e-6,0,0,-1e-6,1,2,3,4\n1000,6,1e-6,0,0,-1e-6,1,2\n", 3, "fy_re"),
        (GOOD_HEADER + "\n1000,5,1e-6,0,0,-1e-6,1,2,3,4\n\n2000,6,1e-6,0,0,-1e-6,1,2,3,4\n", 4, "spin_rpm"),
        (
            GOOD_HEADER + ",gamma2_xfx,gamma2_yfx,gamma2_xfy,gamma2_yfy\n1000,5,1e-6,0,0,-1e-6,1,2,3,4,1,1,1.5,1\n",
            2,
            "gamma2_xfy",
        ),
        (GOOD_HEADER + ",gamma2_xfx\n1000,5,1e-6,0,0,-1e-6,1,2,3,4,1\n", 1, "gamma2_yfx"),
        (GOOD_HEADER + "\n1000,5,1e-6,0,0,-1e-6,1,2,3,nan\n", 2, "fy_im"),
    ],
    ids=[
        "not-a-number",
        "missing-column",
        "orbit-zero",
        "short-row",
        "two-spins",
        "gamma-range",
        "gamma-incomplete",
        "nan",
    ],
)
def test_malformed_table_names_line_and_column(runner, tmp_path, text, line, column):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    res = runner.invoke(app, ["identify", str(path), "--model", "kc8", "--json"])
    assert res.exit_code == 2
    assert res.stdout == ""
    assert f"line {line}" in res.stderr and f"column '{column}'" in res.stderr and str(path) in res.stderr


def test_missing_file_exit_2(runner, tmp_path):
    res = runner.invoke(app, ["identify", str(tmp_path / "none.csv"), "--model", "kc8", "--json"])
    assert res.exit_code == 2 and res.stdout == "" and "none.csv" in res.stderr


def test_real_process_streams(table_csv, tmp_path):
    """The installed entry point as a user runs it: stdout pure JSON, refusals on stderr."""
    ok = orbitrig("identify", str(table_csv), "--model", "kc7", "--json", timeout=60, columns=None)
    assert ok.returncode == 0, ok.stderr
    assert json.loads(ok.stdout)["n_coefficients"] == 7
    bad = tmp_path / "bad.csv"
    bad.write_text(GOOD_HEADER + "\n1000,5,1e-6,0,0,-1e-6,1,2,3,x\n")
    err = orbitrig("identify", str(bad), "--model", "kc7", "--json", timeout=60, columns=None)
    assert err.returncode == 2 and err.stdout == ""
    assert "line 2" in err.stderr and "column 'fy_im'" in err.stderr


def test_exactly_determined_table_has_null_std_errors_and_valid_json(runner, tmp_path):
    path = tmp_path / "t.csv"
    true = truth("kc8", {"K": (0,), "C": (0,)})
    write_orbit_table(path, orbit_table(true, frequencies(2), ("forward",)))  # 8 equations, 8 unknowns
    res = runner.invoke(app, ["identify", str(path), "--model", "kc8", "--json"])
    assert res.exit_code == 0, res.stderr
    d = json.loads(res.stdout)
    assert all(v is None for v in d["std_errors"].values())
    assert d["coefficients"]["Kxx"] == pytest.approx(keys_of(true)["Kxx"], rel=1e-9)


def test_ill_conditioned_fit_warns_on_stderr_and_in_json(runner, tmp_path):
    true = truth("kc8", {"K": (0, 1), "C": (0, 1)})
    fwd = orbit_table(true, frequencies(8), ("forward",))
    bwd = orbit_table(true, frequencies(8), ("backward",), radius=5e-9)  # backward whirl 1000 times smaller
    table = type(fwd)(
        fwd.spin,
        np.r_[fwd.orbit, bwd.orbit],
        np.r_[fwd.x, bwd.x],
        np.r_[fwd.y, bwd.y],
        np.r_[fwd.fx, bwd.fx],
        np.r_[fwd.fy, bwd.fy],
    )
    path = tmp_path / "t.csv"
    write_orbit_table(path, table)
    res = runner.invoke(app, ["identify", str(path), "--model", "kc8", "--freq-dep", "power:1"])
    assert res.exit_code == 0 and "warning: ill-conditioned" in res.stderr and "warning" not in res.stdout
    res = runner.invoke(app, ["identify", str(path), "--model", "kc8", "--freq-dep", "power:1", "--json"])
    d = json.loads(res.stdout)
    assert res.exit_code == 0 and d["warnings"][0].startswith("ill-conditioned") and res.stderr == ""
