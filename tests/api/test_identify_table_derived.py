"""docs/api.md: `orbitrig.identify_table` returns a Fit, whose `derived` holds the effective
damping, direct dynamic stiffness and whirl frequency ratio and whose `adequacy` holds a
frequency-dependent fit's test against the constant fit. A Fit made from a table in memory
had neither (an empty DataFrame and None, silently): they are formed here as the sweep forms
them, at the table's orbit frequencies on the fit's statistical covariance."""

from __future__ import annotations

import numpy as np
import pytest

import orbitrig
from reduction.adequacy import frequency_dependence
from reduction.identify import identify
from orbitrig.store.orbit_table import read_orbit_table


@pytest.fixture(scope="module")
def table(sim_run):
    return orbitrig.open_run(sim_run).table(0, "piezo")


def test_derived_of_a_table_in_memory(table):
    fit = orbitrig.identify_table(table, model="kcd11")
    d = fit.derived
    c = fit.coefficients["value"]
    omega = 2 * np.pi * np.unique(table["orbit_hz"].to_numpy())
    np.testing.assert_allclose(d.index.to_numpy(), omega / (2 * np.pi), rtol=1e-12)
    np.testing.assert_allclose(d["c_eff_xx"], c["Cxx"] - c["Kxy"] / omega, rtol=1e-9)
    np.testing.assert_allclose(d["c_eff_yy"], c["Cyy"] + c["Kyx"] / omega, rtol=1e-9)
    spin = 2 * np.pi * table["spin_rpm"].iloc[0] / 60
    np.testing.assert_allclose(d["wfr"], (c["Kxy"] - c["Kyx"]) / (spin * (c["Cxx"] + c["Cyy"])), rtol=1e-9)
    assert np.all(d["c_eff_xx_std"] > 0) and np.all(d["wfr_std"] > 0)
    assert d.attrs["covariance"] == "statistical" and d.attrs["units"]["c_eff_xx"] == "N s/m"
    assert set(d.columns) >= {"h_forward", "h_backward", "h_forward_std_re", "h_backward_std_im"}
    assert fit.adequacy is None  # a constant fit is tested against nothing


def test_adequacy_of_a_frequency_dependent_fit(table, sim_run, tmp_path):
    fit = orbitrig.identify_table(table, model="kcd11", freq_dep="power:1")
    a = fit.adequacy
    assert a is not None and a["constant"] == "kcd11 none ols" and a["test"] == "likelihood ratio"
    assert a["verdict"].startswith("frequency dependence supported: ")
    path = tmp_path / "t.csv"
    table.drop(columns="direction").to_csv(path, index=False)  # the same table through the CSV reader
    t = read_orbit_table(path)
    expected = frequency_dependence(identify(t, model="kcd11"), identify(t, model="kcd11", freq_dep="power:1"))
    assert a["p_value"] == pytest.approx(expected.p_value, rel=1e-9)
    assert a["statistic"] == pytest.approx(expected.statistic, rel=1e-9)
    assert not fit.derived.empty
