"""The Python API (docs/api.md) against h5py reading run.h5 directly: operating points,
orbit tables with the whirl direction, coefficients with std and U, covariance with its
names, budget, derived quantities, truth and the averaged waveforms; identify_table on a
table in memory reproduces the stored fit; `import orbitrig` stays cheap."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import h5py
import numpy as np
import pytest

import orbitrig
from orbitrig.store.fit_record import BUDGET_PARTS, expanded_uncertainty

from support.paths import ROOT

IDENT = "points/0000/identification/piezo__kcd11__none__ols"


@pytest.fixture(scope="module")
def run(sim_run):
    return orbitrig.open_run(sim_run)


@pytest.fixture(scope="module")
def h5(sim_run):
    with h5py.File(sim_run / "run.h5", "r") as f:
        yield f


def test_import_is_cheap_and_plain_access_needs_no_pandas(sim_run):
    code = (
        "import sys, orbitrig; heavy = ('pandas', 'xarray', 'h5py', 'scipy', 'matplotlib');"
        "print(sorted(m for m in heavy if m in sys.modules));"
        f"r = orbitrig.open_run({str(sim_run)!r}); n = len(r.fits());"
        "print(n, sorted(m for m in ('pandas', 'xarray') if m in sys.modules))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code],
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    ).stdout.splitlines()
    assert out == ["[]", "4 []"]


def test_points_are_the_stored_settings(run, h5):
    points = run.points
    a = h5["points/0000"].attrs
    assert list(points.index) == [0]
    row = points.loc[0]
    assert row.spin == pytest.approx(float(a["spin"])) and row.spin_rpm == pytest.approx(1000.0)
    assert row.recess_pressure == pytest.approx(0.4826e6) and row.dynamic_eccentricity == pytest.approx(0.096)
    assert bool(row.complete) and row.n_frequencies == 10
    assert points.attrs["units"]["recess_pressure"] == "Pa" and points.attrs["units"]["spin"] == "rad/s"


def test_table_and_direction(run, h5):
    t = run.table(0, "piezo")
    g = h5["points/0000/table/piezo"]
    np.testing.assert_array_equal(t.fx_re + 1j * t.fx_im, g["fx"][()])
    np.testing.assert_allclose(t.orbit_hz, g["orbit"][()] / (2 * np.pi), rtol=1e-15)
    truth_orbit = h5["points/0000/truth/orbit"][()]  # the simulator's signed speed of each row
    np.testing.assert_array_equal(t.direction, np.sign(truth_orbit))
    assert t.attrs["units"]["x_re"] == "m" and t.attrs["units"]["direction"] == "1"
    with pytest.raises(KeyError, match="tables: piezo, strain"):
        run.table(0, "laser")


def test_coefficients_std_U_against_run_h5(run, h5):
    coef = run.coefficients
    row = coef[(coef.point == 0) & (coef.lms == "piezo") & (coef.model == "kcd11")].iloc[0]
    g = h5[IDENT]
    names = list(g["names"].asstr()[()])
    value, std = g["coefficients"][()], g["std_errors"][()]
    expanded = g["uncertainty/expanded"][()]
    for k, name in enumerate(names):
        assert row[name] == value[k] and row[f"{name}_std"] == std[k] and row[f"{name}_U"] == expanded[k]
    assert coef.attrs["units"]["Cxy_U"] == "N s/m"
    assert len(coef) == 4 and set(coef.model) == {"kc8", "kcd11"}


def test_U_without_a_budget_is_twice_the_standard_error():
    result = {"coefficients": {"Kxx": 1.0, "Cxx": 2.0}, "std_errors": {"Kxx": 0.1, "Cxx": None}}
    assert expanded_uncertainty(result) == {"Kxx": 0.2, "Cxx": pytest.approx(float("nan"), nan_ok=True)}
    result["uncertainty"] = {"k": 2, "expanded": {"Kxx": 0.5, "Cxx": 0.7}}
    assert expanded_uncertainty(result) == {"Kxx": 0.5, "Cxx": 0.7}


def test_fit_covariance_budget_derived(run, h5):
    fit = run.fit(0, "piezo", "kcd11")
    g = h5[IDENT]
    cov = fit.covariance
    assert list(cov.index) == list(g["covariance"].attrs["names"]) == list(cov.columns)
    assert cov.shape == (11, 11) and "Dyx" not in cov.index  # kcd11: Dyx = Dxy, 11 free of 12
    np.testing.assert_array_equal(cov.to_numpy(), g["covariance"][()])
    table = fit.coefficients
    np.testing.assert_array_equal(table["combined"], g["uncertainty/combined"][()])
    np.testing.assert_allclose(table["U"], 2 * table["combined"], rtol=1e-12)
    derived = fit.derived
    np.testing.assert_array_equal(derived["c_eff_xx"], g["derived/c_eff_xx"][()])
    np.testing.assert_array_equal(derived.index, g["derived/orbit_hz"][()])
    assert derived.attrs["units"]["c_eff_xx"] == "N s/m"
    adequacy = run.fit(0, "piezo", "kc8").adequacy
    assert adequacy is None  # constant fits have no frequency-dependence test
    assert fit.lms_consistency["pair"] == "piezo - strain"
    with pytest.raises(KeyError, match=r"\('piezo', 'kc8', 'none', 'ols'\)"):
        run.fit(0, "piezo", "kc7")


def test_coefficient_and_covariance_units_apply_in_pint(run, h5):
    """A fit's tables hold a unit per row: attrs row_units (coefficients) and entry_units
    (covariance), each a unit pint parses and the one run.h5 states."""
    from support.units import UREG

    g = h5[IDENT]
    fit = run.fit(0, "piezo", "kcd11")
    table = fit.coefficients
    stated = {k: g["coefficients"].attrs[f"units_{k}"] for k in table.index}
    assert table.attrs["row_units"] == stated == dict(zip(table.index, table["unit"]))
    assert set(table.attrs["row_unit_columns"]) == {"value", "std", "U", *BUDGET_PARTS, "true"}  # true: --sim
    assert all(u == "" for u in table.attrs["units"].values())  # only the text column `unit` has one unit
    cxx = UREG.Quantity(table.loc["Cxx", "U"], table.attrs["row_units"]["Cxx"]).to("kN*s/m")
    assert cxx.magnitude == pytest.approx(table.loc["Cxx", "U"] * 1e-3)
    cov = fit.covariance
    assert cov.attrs["units"] == {} and list(cov.attrs["row_units"]) == list(cov.index)
    for i in cov.index:
        for j in cov.columns:
            unit = UREG.parse_units(cov.attrs["entry_units"][i][j])
            assert unit == UREG.parse_units(stated[i]) * UREG.parse_units(stated[j]), (i, j)
    var = UREG.Quantity(cov.loc["Cxx", "Cxx"], cov.attrs["entry_units"]["Cxx"]["Cxx"])
    assert np.sqrt(var).to("N*s/m").magnitude == pytest.approx(table.loc["Cxx", "std"], rel=1e-9)
    for frame in (run.points, run.table(0, "piezo"), run.coefficients, fit.derived):
        for unit in frame.attrs["units"].values():
            UREG.parse_units(unit)


def test_truth_is_arrays_of_the_stated_shapes_and_units(run, h5):
    """docs/api.md: Z_re, Z_im (n, 2, 2) at the rows' signed orbit (n,) rad/s, K0, C0, D0 (2, 2), SI;
    the same numbers as run.h5's truth datasets, one row per row of the point's orbit table."""
    truth, g = run.truth(0), h5["points/0000/truth"]
    n = len(run.table(0, "piezo"))
    assert n == 10  # 5 orbit frequencies, both ways
    shapes = {
        k: (type(truth[k]), truth[k].dtype, truth[k].shape) for k in ("orbit", "orbit_hz", "Z_re", "Z_im", "band")
    }
    shapes |= {k: (type(truth[k]), truth[k].dtype, truth[k].shape) for k in ("K0", "C0", "D0")}
    rows, mat = (n,), (2, 2)
    assert shapes == {
        **{k: (np.ndarray, np.float64, rows) for k in ("orbit", "orbit_hz")},
        **{k: (np.ndarray, np.float64, (n, 2, 2)) for k in ("Z_re", "Z_im")},
        "band": (np.ndarray, np.float64, g["fits/band"].shape),  # m: the point's |Omega|, each measured speed
        **{k: (np.ndarray, np.float64, mat) for k in ("K0", "C0", "D0")},
    }
    np.testing.assert_array_equal(truth["Z_re"] + 1j * truth["Z_im"], g["Z"][()])
    np.testing.assert_array_equal(truth["orbit"], g["orbit"][()])
    np.testing.assert_array_equal(truth["band"], g["fits/band"][()])
    for m in "KCD":
        np.testing.assert_array_equal(truth[f"{m}0"], g[f"fits/constant/{m}"][()])
        np.testing.assert_array_equal(truth["fits"]["constant"][m], truth[f"{m}0"])
        assert (
            truth["units"][f"{m}0"] == truth["fits"]["constant"]["units"][m] == g[f"fits/constant/{m}"].attrs["units"]
        )
    assert {k: truth["units"][k] for k in ("orbit", "Z_re", "band")} == {
        "orbit": "rad/s",
        "Z_re": "N/m",
        "band": "rad/s",
    }
    assert truth["units"]["Z_re"] == g["Z"].attrs["units"] and truth["units"]["orbit"] == g["orbit"].attrs["units"]
    power = truth["fits"]["power"]
    assert power["exponents"] == tuple(g["fits/power"].attrs["exponents"])
    for k in ("K0", "Km", "C0", "Cn", "D0", "Dp"):
        assert power[k].shape == mat and power["units"][k] == g[f"fits/power/{k}"].attrs["units"], k
    np.testing.assert_array_equal(truth["orbit"] < 0, run.table(0, "piezo")["direction"].to_numpy() < 0)
    assert truth["definition"] == json.loads(g.attrs["json"])["definition"]


def test_identify_table_reproduces_the_stored_fit(run):
    stored = run.fit(0, "strain", "kcd11").coefficients
    again = orbitrig.identify_table(run.table(0, "strain"), model="kcd11").coefficients
    np.testing.assert_allclose(again["value"], stored["value"], rtol=1e-9)
    np.testing.assert_allclose(again["std"], stored["std"], rtol=1e-9)
    np.testing.assert_allclose(again["U"], 2 * stored["std"], rtol=1e-9)  # no budget in memory


def test_a_fit_shows_what_it_is(run):
    """As a notebook cell shows it: a stored fit by its point and key, one from a table in
    memory by its model alone (it was `Fit(point=-1, __kcd11__none__ols)`)."""
    assert repr(run.fit(0, "strain", "kcd11")) == "Fit(point=0, strain__kcd11__none__ols)"
    fit = orbitrig.identify_table(run.table(0, "strain"), model="kc8", freq_dep="power:1", method="wls")
    assert repr(fit) == "Fit(kc8 power:1 wls, from a table in memory)"


def test_waveforms(run, h5, sim_run):
    wave = run.waveforms(0)
    assert wave["mean"].dims == ("block", "channel", "angle")
    g = h5["points/0000/frequencies/02_fwd"]
    np.testing.assert_array_equal(wave["mean"].sel(block="02_fwd").values, g["mean"][()])
    np.testing.assert_allclose(wave["theta"].sel(block="02_fwd").values, 2 * np.pi * g["slots"][()] / 360)
    np.testing.assert_array_equal(wave["phasor"].sel(block="02_fwd").values, g["phasors"][()])
    assert wave["mean"].attrs["units_fx_piezo"] == "N" and wave["mean"].attrs["units_x_a"] == "m"
    assert wave["orbit_hz"].attrs["units"] == "Hz" and wave.sizes["block"] == 10
    assert int(wave["direction"].sel(block="02_fwd")) == 1 and int(wave["n_records"][0]) == 10


def test_a_table_without_stated_uncertainties_gets_students_coverage_factor(run):
    """Without u_* the covariance comes from the residual (interval student_t): U is t at
    95.45 % with the fit's dof times the standard error, not 2 x (which covers 89 % at dof 4)."""
    from scipy import stats

    table = run.table(0, "strain")
    bare = table.drop(columns=[c for c in table.columns if c.startswith("u_")]).iloc[:3]
    fit = orbitrig.identify_table(bare, model="kc8")
    assert fit.result["interval"] == "student_t" and fit.result["dof"] == 4
    k = (fit.coefficients["U"] / fit.coefficients["std"]).to_numpy()
    assert np.allclose(k, stats.t.ppf(0.5 + 0.9545 / 2, 4), rtol=1e-9) and 2.86 < k[0] < 2.88
    stated = orbitrig.identify_table(table, model="kc8")
    assert stated.result["interval"] == "normal"
    np.testing.assert_allclose(stated.coefficients["U"], 2 * stated.coefficients["std"], rtol=1e-12)
