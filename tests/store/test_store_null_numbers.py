"""coefficients.csv from an identification whose JSON carries null numbers (the identify
output maps non-finite values to null): empty cells, never a crash of the point's storage
(which would fail the run)."""

import csv

import numpy as np

from orbitrig import config as cfg
from orbitrig.config import ModelSpec
from orbitrig.run.plan import operating_points
from orbitrig.store.writer import PointResults, RunStore
from reduction.table import OrbitTable


def test_null_condition_number_coefficient_and_std_error_give_empty_cells(tmp_path):
    rig, m = cfg.load_rig(), cfg.load_matrix(cfg.default_matrix_path("demo"))
    p = operating_points(m, rig)[0]
    t = OrbitTable(
        spin=p.spin,
        orbit=np.array([1.0, 2.0]),
        x=np.ones(2, complex),
        y=-1j * np.ones(2),
        fx=np.ones(2, complex),
        fy=np.ones(2, complex),
    )
    spec = ModelSpec(model="kc8")
    ident = {
        "model": "kc8",
        "freq_dep": "none",
        "method": "ols",
        "n_coefficients": 8,
        "min_frequencies": 2,
        "n_frequencies": 2,
        "coefficients": {"Kxx": 3e7, "Kxy": None},
        "std_errors": {"Kxx": None, "Kxy": None},
        "condition_number": None,
        "residual_rms": None,
        "fit": [],
    }
    truth = {"orbit_hz": [1.0], "K0": [[3.1e7, 1e6], [0, 3e7]], "C0": [[8e4, 0], [0, 8e4]], "D0": [[0, 0], [0, 0]]}
    s = RunStore.create(tmp_path, rig_text=rig.text, matrix_text=m.text, matrix_name=m.name, sim=True)
    s.begin_point(p)
    s.write_results(
        p.index, PointResults({"piezo": t}, {("piezo", spec.key): {"spec": spec, "json": ident}}, {}, truth)
    )
    s.complete_point(p.index)  # rewrites coefficients.csv
    rows = list(csv.DictReader(open(s.csv_path, encoding="utf-8")))
    assert len(rows) == 1
    r = rows[0]
    assert (r["condition_number"], r["residual_rms [N]"], r["Kxy [N/m]"], r["Kxx_std [N/m]"]) == ("", "", "", "")
    assert float(r["Kxx [N/m]"]) == 3e7 and float(r["true_Kxy [N/m]"]) == 1e6
