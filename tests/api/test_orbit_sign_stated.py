"""Every `orbit` dataset says its sign: an orbit table's rows and the derived quantities'
frequencies hold |Omega| (> 0, the whirl direction in the phasors), the simulator's truth the
same rows' Omega signed. Both sit in one point group (and in run.mat beside each other: the
table's `orbit` and `truth.orbit`), and said only "orbit speed Omega"."""

from __future__ import annotations

import h5py
import numpy as np
from scipy.io import loadmat

import orbitrig
from support.cli_helpers import orbitrig as orbitrig_cli

DERIVED = "points/0000/identification/piezo__kcd11__none__ols/derived/orbit"


def test_run_h5_states_the_sign_of_each_orbit(sim_run):
    direction = orbitrig.open_run(sim_run).table(0)["direction"].to_numpy()
    assert set(direction) == {1, -1}
    with h5py.File(sim_run / "run.h5", "r") as f:
        table, truth, derived = f["points/0000/table/piezo/orbit"], f["points/0000/truth/orbit"], f[DERIVED]
        assert np.all(table[()] > 0) and table.attrs["meaning"].startswith("|Omega| > 0: the whirl direction")
        np.testing.assert_array_equal(np.sign(truth[()]), direction)  # the same rows, signed
        assert truth.attrs["meaning"] == "signed (< 0 backward)"
        assert np.all(derived[()] > 0) and derived.attrs["meaning"] == "|Omega| > 0, as planned"
        assert "attribute meaning" in table.attrs["description"]


def test_mat_states_the_table_orbit_and_truth_orbit_signs(sim_run, tmp_path):
    p = orbitrig_cli("export", str(sim_run), "--format", "mat", "--out", str(tmp_path))
    assert p.returncode == 0, p.stderr
    m = loadmat(tmp_path / "run.mat", simplify_cells=True)
    point = m["points"]["p0000"]
    backward = point["piezo"]["direction"] < 0
    assert np.all(point["piezo"]["orbit"] > 0) and np.all(point["truth"]["orbit"][backward] < 0)
    convention = m["unit_rules"]["convention"]
    assert "table: |Omega| > 0" in convention and "truth.orbit: signed (< 0 backward)" in convention
