"""The simulator's true Z is stored beside each row's signed orbit, but it is a function of
|Omega| (one Z for both whirl directions, the direction being in the table's phasors): a
model set against it is K + i|Omega| C - Omega^2 D. Taken at the signed orbit it is the complex
conjugate at every backward row, off by 2 |Omega| C_xx on the diagonal there (most of |Z| at the
demo's top speeds).
run.h5 says so in the Z dataset's `convention`; run.mat and run.tdms, which a lab reads without
run.h5, say the same (`unit_rules.truth`, the truth group's `convention` and `form`). Read with
h5py, scipy.io.loadmat and npTDMS, as a lab reads them."""

from __future__ import annotations

import h5py
import numpy as np
import pytest
from nptdms import TdmsFile
from scipy.io import loadmat

from orbitrig.store.export import export_run


@pytest.fixture(scope="module")
def exported(sim_run, tmp_path_factory):
    out = tmp_path_factory.mktemp("export_truth_convention")
    for fmt in ("mat", "tdms"):
        export_run(sim_run, fmt, out)
    return out


@pytest.fixture(scope="module")
def stated(sim_run):
    with h5py.File(sim_run / "run.h5", "r") as f:
        truth = f["points/0000/truth"]
        return truth["Z"].attrs["convention"], truth["fits/power"].attrs["form"]


def test_the_true_z_is_the_constant_model_at_abs_omega_not_at_the_signed_orbit(exported):
    t = loadmat(exported / "run.mat", simplify_cells=True)["points"]["p0000"]["truth"]
    omega, z = np.ravel(t["orbit"]), t["Z"]  # the clean scenario: Z is exactly a constant K, C, D
    assert np.any(omega < 0) and np.any(omega > 0)

    def model(w):
        return t["K0"] + 1j * w[:, None, None] * t["C0"] - (w**2)[:, None, None] * t["D0"]

    scale = np.abs(z).max()
    assert np.abs(model(np.abs(omega)) - z).max() < 1e-6 * scale
    backward = omega < 0
    off = np.abs(model(omega) - z)[backward].max(axis=(1, 2))
    assert np.all(off > 0.05 * np.abs(z[backward]).max(axis=(1, 2)))  # what a reader would get wrong


def test_run_mat_states_how_z_depends_on_omega(exported, stated):
    convention, form = stated
    assert "Z = K + i|Omega| C - Omega^2 D" in convention and "not K + i Omega C" in convention
    rule = loadmat(exported / "run.mat", simplify_cells=True)["unit_rules"]["truth"]
    assert convention in rule and form in rule


def test_run_tdms_states_how_z_depends_on_omega(exported, stated):
    convention, form = stated
    group = TdmsFile.read(exported / "run.tdms")["truth 0000"]
    assert group.properties["convention"] == convention
    assert group.properties["form"] == form
    assert form == "K = K0 + |Omega|^m Km, C = C0 + |Omega|^n Cn, D = D0 + |Omega|^p Dp (Eq. 15)"
