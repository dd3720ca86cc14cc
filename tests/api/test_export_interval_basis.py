"""Every export publishes ``interval_95`` with its basis: value -+ U, U = k x the combined
standard uncertainty where the rig stated a calibration uncertainty (``interval_95_basis``
"combined"), else k x the standard error ("statistical only"); the fit's own statistical
95 % interval stays as ``interval_95_statistical``. Read back with csv, npTDMS,
scipy.io.loadmat and h5py against the identification JSON in run.h5."""

from __future__ import annotations

import csv
import json

import h5py
import numpy as np
import pytest
from nptdms import TdmsFile
from scipy.io import loadmat

from orbitrig.store.export import export_run

FIT = "piezo__kcd11__none__ols"


def _stored(run) -> dict:
    with h5py.File(run / "run.h5", "r") as f:
        return json.loads(f[f"points/0000/identification/{FIT}"].attrs["json"])


def _expected(d: dict) -> tuple[list[str], np.ndarray, np.ndarray]:
    """names, value -+ U (U = k x combined where stored) and the statistical confidence_95."""
    names = list(d["coefficients"])
    unc = d.get("uncertainty") or {}
    if unc.get("combined"):
        U = np.array([unc["k"] * unc["combined"][k] for k in names])
    else:
        U = np.array([2.0 * d["std_errors"][k] for k in names])  # normal interval: k = 2
    value = np.array([d["coefficients"][k] for k in names])
    return names, np.stack([value - U, value + U], axis=1), np.array([d["confidence_95"][k] for k in names])


@pytest.fixture(scope="module", params=["sim_run", "synthetic_run"])
def case(request, tmp_path_factory):
    run = request.getfixturevalue(request.param)
    out = tmp_path_factory.mktemp(f"interval_{request.param}")
    for fmt in ("csv", "mat", "tdms", "h5"):
        export_run(run, fmt, out / fmt)
    d = _stored(run)
    basis = "combined" if (d.get("uncertainty") or {}).get("combined") else "statistical only"
    assert basis == ("combined" if request.param == "sim_run" else "statistical only")
    return d, basis, out


def test_csv_interval_is_value_pm_k_u_with_its_basis(case):
    d, basis, out = case
    names, interval, stat = _expected(d)
    with open(out / "csv" / "fits.csv", newline="", encoding="utf-8") as fh:
        rows = [
            r
            for r in csv.DictReader(fh)
            if (r["point"], r["lms"], r["model"], r["freq_dep"], r["method"]) == ("0", "piezo", "kcd11", "none", "ols")
        ]
    assert [r["name"] for r in rows] == names
    got = np.array([[float(r["interval_95_low"]), float(r["interval_95_high"])] for r in rows])
    np.testing.assert_allclose(got, interval, rtol=1e-12)
    got = np.array([[float(r["interval_95_statistical_low"]), float(r["interval_95_statistical_high"])] for r in rows])
    np.testing.assert_array_equal(got, stat)
    assert {r["interval_95_basis"] for r in rows} == {basis}
    with open(out / "csv" / "fit_properties.csv", newline="", encoding="utf-8") as fh:
        props = {
            r["name"]: r["value"]
            for r in csv.DictReader(fh)
            if (r["point"], r["lms"], r["model"], r["freq_dep"]) == ("0", "piezo", "kcd11", "none")
        }
    assert props["interval_95_basis"] == basis and float(props["k"]) == 2.0


def test_mat_interval_and_basis(case):
    d, basis, out = case
    names, interval, stat = _expected(d)
    fit = loadmat(out / "mat" / "run.mat", simplify_cells=True)["points"]["p0000"]["identification"][FIT]
    assert list(fit["names"]) == names and fit["interval_95_basis"] == basis
    np.testing.assert_allclose(fit["interval_95"], interval, rtol=1e-12)
    np.testing.assert_array_equal(fit["interval_95_statistical"], stat)


def test_tdms_interval_and_basis(case):
    d, basis, out = case
    names, interval, stat = _expected(d)
    g = TdmsFile.read(out / "tdms" / "run.tdms")[f"fit 0000 {FIT}"]
    rows = list(g["quantity"][:])
    lo, hi, slo, shi = (
        rows.index(q)
        for q in ("interval_95_low", "interval_95_high", "interval_95_statistical_low", "interval_95_statistical_high")
    )
    assert g.properties["interval_95_basis"] == basis
    for j, name in enumerate(names):
        np.testing.assert_allclose([g[name][lo], g[name][hi]], interval[j], rtol=1e-12)
        assert (g[name][slo], g[name][shi]) == tuple(stat[j])


@pytest.mark.parametrize("where", ["run", "export"])
def test_h5_interval_and_basis(case, where, sim_run, synthetic_run):
    d, basis, out = case
    names, interval, stat = _expected(d)
    run = sim_run if basis == "combined" else synthetic_run
    path = run / "run.h5" if where == "run" else out / "h5" / "run.h5"
    with h5py.File(path, "r") as f:
        g = f[f"points/0000/identification/{FIT}"]
        assert g.attrs["interval_95_basis"] == basis
        np.testing.assert_allclose(g["interval_95"][()], interval, rtol=1e-12)
        np.testing.assert_array_equal(g["interval_95_statistical"][()], stat)
        assert "statistical only" in g["interval_95_statistical"].attrs["description"]
