"""Every export carries what run.h5 holds beside the numbers: the calibration record's and the
simulator scenario's TOML text (provenance; multi-line text read back unchanged from
provenance.csv, run.mat and the TDMS root), the derived quantities' C_eff zero crossings
(rad/s, with their std) and covariance basis, and the adequacy test's name and numbers. Read
with csv, scipy.io.loadmat and npTDMS against run.h5 read with h5py; the API gives the texts."""

from __future__ import annotations

import csv

import h5py
import numpy as np
import pytest
from nptdms import TdmsFile
from scipy.io import loadmat

import orbitrig
from orbitrig.store.export import export_run

RECORD = (
    '# calibration record, "quoted", with commas, and several lines\n'
    'date = "2026-11-26T21:47:32Z"\n'
    "[runout]\n"
    'spin_rpm = 1000.0\nx_re_um = [0.5, -0.25]\nnote = "a, b"\n'
)
SCENARIO = ("bearing.toml", "# a simulator scenario\n[bearing]\nK0 = [[3.0e7, 5.0e6],\n      [-5.0e6, 3.0e7]]\n")
FIT, POWER = "piezo__kcd11__none__ols", "piezo__kcd11__power_1__ols"


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    from support.report_synthetic import write_synthetic_run

    return write_synthetic_run(
        tmp_path_factory.mktemp("texts") / "run",
        n_points=1,
        incomplete=0,
        provenance={"calibration_record": "2026-11-26T214732Z-runout", "calibration_record_sha256": "ab" * 32},
        record_text=RECORD,
        scenario=SCENARIO,
    )


@pytest.fixture(scope="module")
def stored(run):
    """What run.h5 says, read with h5py."""
    with h5py.File(run / "run.h5", "r") as f:
        fits = f["points/0000/identification"]
        out = {
            "record": f.attrs["calibration_record_text"],
            "scenario": (f.attrs["sim_scenario_name"], f.attrs["sim_scenario_config"]),
            "zero": {k: fits[f"{FIT}/derived/c_eff_zero_{k}"][()] for k in ("xx", "yy")},
            "zero_units": fits[f"{FIT}/derived/c_eff_zero_xx"].attrs["units"],
            "basis": fits[f"{FIT}/derived"].attrs["covariance"],
            "adequacy": dict(fits[f"{POWER}/adequacy"].attrs),
        }
    assert out["record"] == RECORD and tuple(out["scenario"]) == SCENARIO
    assert out["zero"]["xx"].shape == (2,) and 10 < out["zero"]["xx"][0] < 200 and out["zero_units"] == "rad/s"
    assert out["basis"] == "statistical" and out["adequacy"]["test"] == "likelihood ratio"
    return out


@pytest.fixture(scope="module")
def out(run, tmp_path_factory):
    out = tmp_path_factory.mktemp("export")
    for fmt in ("csv", "mat", "tdms"):
        export_run(run, fmt, out)
    return out


def test_csv(run, out, stored):
    with open(out / "provenance.csv", newline="", encoding="utf-8") as fh:
        provenance = dict(csv.reader(fh))
    assert provenance["calibration_record_text"] == RECORD  # multi-line, quotes and commas survive
    api = orbitrig.open_run(run).run  # the API gives the same texts
    assert (api.calibration_record_text, api.sim_scenario_name, api.sim_scenario_config) == (RECORD, *SCENARIO)
    assert (provenance["sim_scenario_name"], provenance["sim_scenario_config"]) == SCENARIO
    with open(out / "fit_properties.csv", newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == ["point", "lms", "model", "freq_dep", "method", "name", "value", "unit"]
    fit = {
        r["name"]: (r["value"], r["unit"])
        for r in rows
        if (r["lms"], r["model"], r["freq_dep"]) == ("piezo", "kcd11", "none")
    }
    for k in ("xx", "yy"):
        omega, std = stored["zero"][k]
        assert fit[f"derived_c_eff_zero_{k}_omega_0"] == (repr(float(omega)), "rad/s")
        assert fit[f"derived_c_eff_zero_{k}_std"] == (repr(float(std)), "rad/s")
    assert fit["derived_covariance"] == ("statistical", "")
    power = {r["name"]: (r["value"], r["unit"]) for r in rows if r["freq_dep"] == "power:1" and r["lms"] == "piezo"}
    a = stored["adequacy"]
    assert power["adequacy_test"] == ("likelihood ratio", "") and power["adequacy_verdict"][0] == a["verdict"]
    assert (float(power["adequacy_dof_numerator"][0]), float(power["adequacy_dof_denominator"][0])) == tuple(a["dof"])
    assert float(power["adequacy_p_value"][0]) == a["p_value"] and power["adequacy_p_value"][1] == "1"
    assert [float(power[f"adequacy_aic_{p}"][0]) for p in ("constant", "fit")] == list(a["aic"])


def test_mat(out, stored):
    m = loadmat(out / "run.mat", simplify_cells=True)
    assert m["run"]["calibration_record_text"] == RECORD
    assert (m["run"]["sim_scenario_name"], m["run"]["sim_scenario_config"]) == SCENARIO
    fit = m["points"]["p0000"]["identification"][FIT]
    for k in ("xx", "yy"):
        np.testing.assert_array_equal(fit["derived"][f"c_eff_zero_{k}"], stored["zero"][k])
        assert fit["derived_units"][f"c_eff_zero_{k}"] == "rad/s"
    assert fit["derived_covariance"] == "statistical"
    power = m["points"]["p0000"]["identification"][POWER]
    a = stored["adequacy"]
    assert power["adequacy_test"] == "likelihood ratio" and power["adequacy_verdict"] == a["verdict"]
    np.testing.assert_array_equal(power["adequacy_dof"], a["dof"])
    np.testing.assert_array_equal(power["adequacy_bic"], a["bic"])
    assert m["units"]["adequacy_dof"] == m["units"]["adequacy_p_value"] == "1"


def test_tdms(out, stored):
    tdms = TdmsFile.read(out / "run.tdms")
    assert tdms.properties["calibration_record_text"] == RECORD
    assert (tdms.properties["sim_scenario_name"], tdms.properties["sim_scenario_config"]) == SCENARIO
    derived = tdms[f"derived 0000 {FIT}"].properties
    for k in ("xx", "yy"):
        omega, std = stored["zero"][k]
        assert (derived[f"c_eff_zero_{k}_omega_0"], derived[f"c_eff_zero_{k}_std"]) == (omega, std)
        assert derived[f"c_eff_zero_{k}_omega_0.unit_string"] == derived[f"c_eff_zero_{k}_std.unit_string"] == "rad/s"
    assert derived["covariance"] == "statistical"
    power = tdms[f"fit 0000 {POWER}"].properties
    a = stored["adequacy"]
    assert power["adequacy_test"] == "likelihood ratio" and power["adequacy_verdict"] == a["verdict"]
    assert (power["adequacy_dof_numerator"], power["adequacy_dof_denominator"]) == tuple(a["dof"])
    assert power["adequacy_statistic"] == a["statistic"] and power["adequacy_statistic.unit_string"] == "1"
