"""run.mat and run.tdms carry the simulator's truth as run.h5 and ``RunData.truth`` give it
(docs/storage.md: each format carries the same content): besides K0, C0, D0 (the constant
best fit), the true Z and the rows' signed ``orbit``, each row's planned ``orbit_hz``, the
``band`` of |Omega| the best fits use and the paper's Eq. 15 best fit (``power_K0``,
``power_Km`` ... ``power_Dp``, ``power_exponents``), each with its unit. Read with
scipy.io.loadmat, npTDMS and pint, as a lab reads them, and compared number for number."""

from __future__ import annotations

import numpy as np
import pint
import pytest
from nptdms import TdmsFile
from scipy.io import loadmat

import orbitrig
from orbitrig.store.export import export_run

UREG = pint.UnitRegistry()
POWER = ("K0", "Km", "C0", "Cn", "D0", "Dp")


@pytest.fixture(scope="module")
def exported(sim_run, tmp_path_factory):
    out = tmp_path_factory.mktemp("export_truth")
    for fmt in ("mat", "tdms"):
        export_run(sim_run, fmt, out)
    return out


@pytest.fixture(scope="module")
def truth(sim_run):
    t = orbitrig.open_run(sim_run).truth(0)
    assert t is not None and "power" in t["fits"] and t["band"].size > 0
    return t


def test_run_mat_carries_the_whole_truth(exported, truth):
    m = loadmat(exported / "run.mat", simplify_cells=True)
    got = m["points"]["p0000"]["truth"]
    power = truth["fits"]["power"]
    for name in ("orbit", "orbit_hz", "band"):
        np.testing.assert_array_equal(np.ravel(got[name]), truth[name], err_msg=name)
        assert got["units"][name] == truth["units"][name] == m["units"][name]
    for term in POWER:
        np.testing.assert_array_equal(got[f"power_{term}"], power[term], err_msg=term)
        assert got["units"][f"power_{term}"] == power["units"][term]
    np.testing.assert_array_equal(np.ravel(got["power_exponents"]), power["exponents"])
    assert got["units"]["power_exponents"] == "1"
    np.testing.assert_array_equal(got["K0"], truth["K0"])  # the constant best fit, as before
    for unit in got["units"].values():
        UREG.parse_units(unit)
    # Km multiplies |Omega|^m (m = 1 here): N/m per rad/s
    km = UREG.Quantity(1.0, got["units"]["power_Km"])
    assert km.dimensionality == (UREG.Quantity(1.0, "N/m") / UREG.Quantity(1.0, "rad/s")).dimensionality


def test_run_tdms_carries_the_whole_truth(exported, truth):
    g = TdmsFile.read(exported / "run.tdms")["truth 0000"]
    power = truth["fits"]["power"]
    for name in ("orbit", "orbit_hz", "band"):
        np.testing.assert_array_equal(g[name][:], truth[name], err_msg=name)
        assert g[name].properties["unit_string"] == truth["units"][name]
    for term in POWER:
        np.testing.assert_array_equal(g[f"power_{term}"][:], np.ravel(power[term]), err_msg=term)  # row-major
        assert g[f"power_{term}"].properties["unit_string"] == power["units"][term]
    np.testing.assert_array_equal(g["power_exponents"][:], power["exponents"])
    assert g["power_exponents"].properties["unit_string"] == "1"
