"""Every export carries each fit's goodness of fit and interval (orbit-table v3): dof, chi2,
p_value, aic, bic, `interval` (normal | student_t) with its confidence level and the
statistical 95 % bounds, the coverage factor k of U and interval_95 = value -+ U with its basis, from the one place all writers read
(export_content.fit_arrays). Read back with csv, npTDMS, scipy.io.loadmat and h5py against
the identification JSON in run.h5; every unit is one pint parses."""

from __future__ import annotations

import csv
import json
import math

import h5py
import numpy as np
import pytest
from nptdms import TdmsFile
from scipy.io import loadmat

from orbitrig.store import export_content as content
from orbitrig.store.export import export_run
from orbitrig.store.fit_record import coverage_of, fit_record
from support.units import UREG

FIT = "piezo__kcd11__none__ols"
QUALITY = ("dof", "chi2", "p_value", "aic", "bic")


@pytest.fixture(scope="module")
def stored(synthetic_run) -> dict:
    """Point 0000's identification JSON of each fit, read with h5py."""
    with h5py.File(synthetic_run / "run.h5", "r") as f:
        return {
            key: (json.loads(g.attrs["json"]) if "json" in g.attrs else None)
            for key, g in f["points/0000/identification"].items()
        }


@pytest.fixture(scope="module")
def exported(synthetic_run, tmp_path_factory):
    out = tmp_path_factory.mktemp("fit_quality")
    for fmt in ("csv", "mat", "tdms", "h5"):
        export_run(synthetic_run, fmt, out / fmt)
    return out


def test_fit_properties_csv(exported, stored):
    assert stored[FIT]["interval"] == "normal" and stored[FIT]["dof"] == 69 and 0 < stored[FIT]["chi2"] < 69
    assert stored["piezo__kcd12__poly_8__ols"] is None  # a refused model
    with open(exported / "csv" / "fit_properties.csv", newline="", encoding="utf-8") as fh:
        rows = [r for r in csv.DictReader(fh) if r["point"] == "0"]

    def key(r) -> str:
        return "__".join((r["lms"], r["model"], r["freq_dep"].replace(":", "_").replace(",", "_"), r["method"]))

    for fit, d in stored.items():
        props = {r["name"]: (r["value"], r["unit"]) for r in rows if key(r) == fit}
        if d is None:
            assert not set(props) & {*QUALITY, "interval", "k"}, fit
            continue
        for name in QUALITY:
            assert float(props[name][0]) == d[name] and props[name][1] == "1", (fit, name)
        assert props["interval"] == (d["interval"], "")
        assert props["confidence_level"] == ("0.95", "1")
        assert float(props["k"][0]) == 2.0 and props["k"][1] == "1"  # normal interval: U = 2 u
        for _, unit in props.values():
            UREG.parse_units(unit)


def test_fits_csv_interval_bounds(exported, stored):
    with open(exported / "csv" / "fits.csv", newline="", encoding="utf-8") as fh:
        rows = [
            r
            for r in csv.DictReader(fh)
            if (r["point"], r["lms"], r["model"], r["freq_dep"]) == ("0", "piezo", "kcd11", "none")
        ]
    ci = stored[FIT]["confidence_95"]
    assert [r["name"] for r in rows] == list(ci)
    for r in rows:
        low, high = ci[r["name"]]
        assert (float(r["interval_95_statistical_low"]), float(r["interval_95_statistical_high"])) == (low, high)
        assert low < float(r["value"]) < high
        U = float(r["U"])  # interval_95 is value -+ U (no budget here: statistical only)
        assert float(r["interval_95_low"]) == pytest.approx(float(r["value"]) - U, rel=1e-12)
        assert float(r["interval_95_high"]) == pytest.approx(float(r["value"]) + U, rel=1e-12)
        assert r["interval_95_basis"] == "statistical only"


def test_tdms_group_properties_and_interval_rows(exported, stored):
    d = stored[FIT]
    g = TdmsFile.read(exported / "tdms" / "run.tdms")[f"fit 0000 {FIT}"]
    p = g.properties
    for name in QUALITY:
        assert p[name] == d[name] and p[f"{name}.unit_string"] == "1", name
    assert p["interval"] == "normal" and "interval.unit_string" not in p
    assert p["confidence_level"] == 0.95 and p["k"] == 2.0 and p["k.unit_string"] == "1"
    rows = list(g["quantity"][:])
    assert rows[:7] == [
        "value",
        "std",
        "U",
        "interval_95_low",
        "interval_95_high",
        "interval_95_statistical_low",
        "interval_95_statistical_high",
    ]
    for name, (low, high) in d["confidence_95"].items():
        assert (g[name][5], g[name][6]) == (low, high)
        assert g[name][3] == pytest.approx(g[name][0] - g[name][2], rel=1e-12)
        assert g[name][2] == pytest.approx(p["k"] * g[name][1], rel=1e-12)  # U = k x std (no budget)


def test_mat_fields_and_units(exported, stored):
    m = loadmat(exported / "mat" / "run.mat", simplify_cells=True)
    fit, d = m["points"]["p0000"]["identification"][FIT], stored[FIT]
    for name in QUALITY:
        assert fit[name] == d[name] and m["units"][name] == "1", name
    assert fit["interval"] == "normal" and fit["confidence_level"] == 0.95 and fit["k"] == 2.0
    assert m["units"]["k"] == m["units"]["confidence_level"] == "1" and "interval" not in m["units"]
    np.testing.assert_array_equal(fit["interval_95_statistical"], [d["confidence_95"][k] for k in fit["names"]])


def test_h5_export_attributes_and_their_mirror(exported, stored):
    d = stored[FIT]
    with h5py.File(exported / "h5" / "run.h5", "r") as f:
        g = f[f"points/0000/identification/{FIT}"]
        for name in QUALITY:
            assert g.attrs[name] == d[name] and g.attrs[f"{name}__units"] == "1", name
        assert g.attrs["interval"] == "normal" and g.attrs["interval__description"]
        assert g.attrs["confidence_level"] == 0.95 and g.attrs["k"] == 2.0 and g.attrs["k__units"] == "1"
        mirror = f[f"attributes/points/0000/identification/{FIT}"]
        assert mirror["interval"][()] == b"normal" and mirror["k"][()] == 2.0  # what GNU Octave's load reads
        refused = f["points/0000/identification/piezo__kcd12__poly_8__ols"]
        assert "interval" not in refused.attrs and "k" not in refused.attrs


def test_k_of_a_fit_without_stated_uncertainty_is_students():
    """A fit whose covariance comes from the residual (interval student_t, dof 4): k is Student's
    t at 95.45 %, U = k std, and the exports say so."""
    result = {
        "coefficients": {"Kxx": 3.0e7, "Cxx": 5.0e4},
        "std_errors": {"Kxx": 1.0e5, "Cxx": 300.0},
        "confidence_95": {"Kxx": [2.97e7, 3.03e7], "Cxx": [4.9e4, 5.1e4]},
        "dof": 4,
        "aic": 12.5,
        "bic": None,
        "interval": "student_t",
    }
    fit = fit_record(0, None, "kc8", "none", "ols", result)
    d = content.fit_arrays(fit)
    assert d["k"] == coverage_of(result) == pytest.approx(2.869, abs=1e-3)
    np.testing.assert_allclose(fit.U, d["k"] * fit.std, rtol=1e-15)
    props = content.fit_properties(fit)
    assert props["interval"] == ("student_t", "") and props["dof"] == (4.0, "1") and props["aic"] == (12.5, "1")
    assert math.isnan(props["bic"][0]) and "chi2" not in props  # null: NaN; absent without u_*
    np.testing.assert_array_equal(d["interval_95_statistical"], [[2.97e7, 3.03e7], [4.9e4, 5.1e4]])
    U = d["k"] * np.array([1.0e5, 300.0])  # interval_95: value -+ U, statistical only
    np.testing.assert_allclose(d["interval_95"], np.stack([fit.value - U, fit.value + U], axis=1), rtol=1e-15)
    assert d["interval_95_basis"] == "statistical only"
