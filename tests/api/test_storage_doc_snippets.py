"""docs/storage.md's reading examples run as written on a simulated run: the Python one (h5py,
pandas) on run.h5 and coefficients.csv, the GNU Octave one on the h5 export."""

from __future__ import annotations

import re

import h5py
import numpy as np

from orbitrig import open_run
from orbitrig.store.export import export_run
from support.octave import octave_eval
from support.paths import ROOT
from support.report_synthetic import write_synthetic_run

STORAGE = (ROOT / "docs" / "storage.md").read_text()


def test_python_reading_example_runs_verbatim(sim_run):
    (code,) = re.findall(r"```python\n(.*?)```", STORAGE, re.S)
    names: dict[str, object] = {}
    exec(compile(code.replace("DIR/", f"{sim_run}/"), "docs/storage.md, python", "exec"), names)
    coef, table, results = names["coef"], names["table"], names["results"]
    with h5py.File(sim_run / "run.h5", "r") as f:
        stored = f["points/0000/identification/piezo__kcd11__none__ols/coefficients"][()]
    np.testing.assert_array_equal(coef["value"].to_numpy(), stored)
    fit = open_run(sim_run).fit(0, "piezo", "kcd11").coefficients  # the same U as the API's
    np.testing.assert_array_equal(coef["U"].to_numpy(), fit["U"].to_numpy())
    assert list(coef.index) == list(fit.index)
    assert coef.loc["Kxx", "unit"] == "N/m" and coef.loc["Cxy", "unit"] == "N s/m" and coef.loc["Dyy", "unit"] == "kg"
    assert len(table) == 10 and np.iscomplexobj(table["fx"].to_numpy())  # 5 ratios x 2 whirl directions
    assert "Kxx [N/m]" in results.columns and len(results) == 4  # piezo, strain x kcd11, kc8


def test_octave_reading_example_runs_verbatim(sim_run, tmp_path):
    _octave_example_runs(sim_run, tmp_path)


def test_octave_reading_example_runs_on_a_run_without_a_calibration_budget(tmp_path):
    """A rig that states no calibration uncertainty stores no uncertainty/ group: the example
    read U from uncertainty.expanded and failed there ("invalid use of undefined value")."""
    run = write_synthetic_run(tmp_path / "run", incomplete=0)  # no stated calibration uncertainty
    with h5py.File(run / "run.h5", "r") as f:
        assert "uncertainty" not in f["points/0000/identification/piezo__kcd11__none__ols"]
    _octave_example_runs(run, tmp_path)


def _octave_example_runs(run, tmp_path) -> None:
    (code,) = re.findall(r"```octave\n(.*?)```", STORAGE, re.S)
    export_run(run, "h5", tmp_path / "export")
    done = octave_eval(code.replace("DIR/", f"{tmp_path}/"), tmp_path)
    errors = [line for line in done.stderr.splitlines() if "error" in line and "preparing to exit" not in line]
    assert done.returncode == 0 and not errors, done.stderr[-2000:]  # (Octave 7's own message at exit aside)
    assert re.search(r"\[1,1\] = Kxx", done.stdout) and re.search(r"\[12,1\] = Dyy", done.stdout)
    assert "ans = N\n" in done.stdout and "ans = orbitrig " in done.stdout
