"""A --sim run's Fit.coefficients carries each coefficient's true value (`true`: the fit's own
truth, the true Z projected onto its model), as fits.csv, run.h5 (`truth`), run.mat and the TDMS
fit groups do: the API alone left it in the nested result JSON."""

from __future__ import annotations

import csv

import h5py
import numpy as np

import orbitrig
from orbitrig.store.export import export_run

FIT = "points/0000/identification/piezo__kcd11__none__ols"


def test_true_column_is_the_stored_truth_and_fits_csv_true(sim_run, tmp_path):
    run = orbitrig.open_run(sim_run)
    coef = run.fit(0, "piezo", "kcd11").coefficients
    assert "true" in coef.attrs["row_unit_columns"]  # in each row's unit
    with h5py.File(sim_run / "run.h5", "r") as f:
        names = list(f[FIT]["names"].asstr()[()])
        np.testing.assert_array_equal(coef.loc[names, "true"].to_numpy(), f[FIT]["truth"][()])
    export_run(sim_run, "csv", tmp_path)
    with open(tmp_path / "fits.csv", newline="") as fh:
        rows = [r for r in csv.DictReader(fh) if (r["point"], r["lms"], r["model"]) == ("0", "piezo", "kcd11")]
    assert {r["name"]: float(r["true"]) for r in rows} == coef["true"].to_dict()


def test_a_table_identified_in_memory_has_no_true_column(sim_run):
    fit = orbitrig.identify_table(orbitrig.open_run(sim_run).table(0), model="kcd11")
    assert "true" not in fit.coefficients.columns
