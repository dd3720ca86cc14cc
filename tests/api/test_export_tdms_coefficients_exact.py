"""The TDMS export's ``coefficients`` group holds the numbers of coefficients.csv's columns as
doubles: each must be the stored value to the last bit (the same as the ``fit`` groups of the
same file and run.h5), not the CSV's display rounding read back (Kxx 33876953.0 beside the fit
group's 33876952.51249599)."""

from __future__ import annotations

import json

import h5py
import numpy as np
from nptdms import TdmsFile

from orbitrig.store.export import export_run
from orbitrig.store.fit_record import expanded_uncertainty
from rigunits import MPA


def _stored_rows(run_h5):
    """(lms, model, freq_dep, method) -> the identify JSON of each fit of point 0, and the settings."""
    with h5py.File(run_h5, "r") as f:
        point = f["points/0000"]
        settings = {
            k: point.attrs[k] for k in ("spin_rpm", "recess_pressure", "pressure_ratio", "dynamic_eccentricity")
        }
        fits = {}
        for g in point["identification"].values():
            if "json" in g.attrs:
                d = json.loads(g.attrs["json"])
                fits[(g.attrs["model"], d["freq_dep"], d["method"], g.name.split("/")[-1].split("__")[0])] = d
    return settings, fits


def test_tdms_coefficients_group_carries_every_number_unrounded(sim_run, tmp_path):
    export_run(sim_run, "tdms", tmp_path)
    settings, fits = _stored_rows(sim_run / "run.h5")
    group = TdmsFile.read(tmp_path / "run.tdms")["coefficients"]
    col = {c.name: c[:] for c in group.channels()}
    assert len(col["lms"]) == len(fits) == 4  # piezo and strain, kcd11 and kc8
    for i in range(len(col["lms"])):
        d = fits[(col["model"][i], col["freq_dep"][i], col["method"][i], col["lms"][i])]
        U = expanded_uncertainty(d)
        for k, v in d["coefficients"].items():
            assert col[k][i] == v, f"{col['lms'][i]} {col['model'][i]} {k}: {col[k][i]!r} != {v!r}"
            assert col[f"{k}_std"][i] == d["std_errors"][k]
            assert col[f"{k}_U"][i] == U[k]
            truth = d["truth"]["coefficients"][k]
            assert col[f"true_{k}"][i] == truth
        assert col["condition_number"][i] == d["condition_number"]
        assert col["residual_rms"][i] == d["residual_rms"]
    assert np.all(col["spin_rpm"] == settings["spin_rpm"])
    assert np.all(col["recess_pressure_mpa"] == settings["recess_pressure"] / MPA)
    assert np.all(col["pressure_ratio"] == settings["pressure_ratio"])
    assert np.all(col["dynamic_eccentricity"] == settings["dynamic_eccentricity"])


def test_tdms_coefficients_group_agrees_with_the_fit_groups(sim_run, tmp_path):
    export_run(sim_run, "tdms", tmp_path)
    tdms = TdmsFile.read(tmp_path / "run.tdms")
    col = {c.name: c[:] for c in tdms["coefficients"].channels()}
    for i in range(len(col["lms"])):
        fit = tdms[f"fit 0000 {col['lms'][i]}__{col['model'][i]}__{col['freq_dep'][i]}__{col['method'][i]}"]
        rows = list(fit["quantity"][:])
        for name in (c.name for c in fit.channels() if c.name != "quantity"):
            assert col[name][i] == fit[name][rows.index("value")]
            assert col[f"{name}_U"][i] == fit[name][rows.index("U")]
            assert col[f"{name}_std"][i] == fit[name][rows.index("std")]
