"""run.coefficients carries each fit's judgement as coefficients.csv does: n_frequencies (rows of
its orbit table), not_determined and warnings, with the same values (one owner: csvfile.fit_cells);
a refused model's are <NA>, "" and ""."""

from __future__ import annotations

import csv

import pandas as pd

import orbitrig
from orbitrig.store.fit_record import fit_record
from orbitrig.store.frames import coefficients_frame
from orbitrig.load_systems import LoadSystem

COLUMNS = ("n_frequencies", "not_determined", "warnings")


def test_run_coefficients_match_coefficients_csv(sim_run):
    coef = orbitrig.open_run(sim_run).coefficients
    with open(sim_run / "coefficients.csv", newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == len(coef) == 4
    for row, (_, api) in zip(rows, coef.iterrows()):
        assert (row["lms"], row["model"]) == (api.lms, api.model)
        assert int(row["n_frequencies"]) == api.n_frequencies == 10
        assert (row["not_determined"], row["warnings"]) == (api.not_determined, api.warnings)
    assert coef.attrs["units"]["n_frequencies"] == "1" and coef.attrs["units"]["warnings"] == ""


def test_not_determined_warnings_and_a_refused_model():
    result = {
        "freq_dep": "none",
        "method": "ols",
        "n_frequencies": 6,
        "coefficients": {"Kxx": 1.0e7, "Cxx": 2.0e3},
        "std_errors": {"Kxx": 1.0e5, "Cxx": 3.0e3},
        "not_determined": ["Cxx"],
        "warnings": ["ill-conditioned:\n  Cxx poorly determined", "chi2 too large"],
    }
    fits = [
        fit_record(0, LoadSystem.PIEZO, "kc8", "none", "ols", result),
        fit_record(0, LoadSystem.PIEZO, "kcd12", "none", "ols", None, "too few frequencies"),
    ]
    coef = coefficients_frame(fits)
    assert list(coef.n_frequencies) == [6, pd.NA]
    assert list(coef.not_determined) == ["Cxx", ""]
    assert list(coef.warnings) == ["ill-conditioned: | Cxx poorly determined | chi2 too large", ""]
