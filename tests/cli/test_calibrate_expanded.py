"""A calibration record states each fit's expanded uncertainty with its coverage factor and
degrees of freedom (docs/calibration.md): U = k u, k Student's t at 95.45 % (2.37 at the loads
fit's 8 dof, where k = 2 covers 91.9 %), so that a reader recomputes u = U / k. A record written
before them loads as before (its u are standard uncertainties, k = 1) and `calibrate show` says so,
with what U = 2 u would cover at its fit's dof.

Real parts: `orbitrig calibrate loads --sim` on the simulator writes the record; `calibrate show`
reads it and an older record typed as records were written before these keys."""

from __future__ import annotations

import re
import shutil
import warnings

import numpy as np
import pytest

from orbitrig import config as cfg
from reduction.statistics import Interval, coverage_factor
from support.cli_helpers import orbitrig, orbitrig_here
from support.paths import ROOT
from support.rig_configs import patient_rig_config

pytestmark = pytest.mark.timeout(240)

K8 = coverage_factor(Interval.STUDENT_T, 8)  # 2.366


def test_a_loads_step_records_dof_k_and_u_beside_u(tmp_path):
    patient_rig_config(tmp_path)
    shutil.copytree(ROOT / "config/calibration", tmp_path / "calibration")
    rig = tmp_path / "rig.toml"
    p = orbitrig("calibrate", "loads", "--sim", "--config", str(rig), "--speedup", "40", timeout=200)
    assert p.returncode == 0, p.stderr
    record = cfg.load_rig(rig).record
    for lms in ("piezo", "strain"):
        g = record.loads[lms]
        assert g.loads == 7 and g.dof == 8  # 2 (7 - 3)
        # the simulator's loads are exact: u is the residuals' alone, k Student's t at the fit's dof
        assert np.allclose(g.gain_k, K8, rtol=1e-9)
        assert np.allclose(np.array(g.gain_U) / np.array(g.gain_k), g.gain_u, rtol=1e-12)
        assert re.search(rf"^{lms}: gain matrix .*; U \[\[.*\]\], k 2\.37, dof 8\), residual", p.stdout, re.M)
    shown = orbitrig_here("calibrate", "show", "--config", str(rig))
    assert shown.returncode == 0, shown.stderr
    assert "\n# [loads.piezo] U = k u at 95.45 %: k 2.37 (Student's t), the fit's dof 8\n" in shown.stdout


def test_a_record_written_before_dof_and_u_loads_and_is_shown_with_its_u_alone(tmp_path):
    shutil.copy(ROOT / "config/rig.toml", tmp_path / "rig.toml")
    shutil.copytree(ROOT / "config/calibration", tmp_path / "calibration")
    rig = cfg.load_rig(tmp_path / "rig.toml")
    data = rig.record.model_dump() | cfg.identity(rig)
    data.update(date="2026-12-01T08:30:00+00:00", step="loads", previous=rig.calibration_record)
    u = [[1.4e-3, 1.4e-3], [1.4e-3, 1.4e-3]]
    data["loads"] = {"strain": {"gain": [[0.98, 0.001], [0.0, 0.99]], "gain_u": u, "loads": 7}}
    data["probes"] = {"x_a": {"gain": 1.007, "gain_u": 6.6e-5, "steps": 5}}
    name, _ = cfg.write_record(tmp_path / "calibration", cfg.CalibrationRecord.model_validate(data))
    text = (tmp_path / "calibration" / f"{name}.toml").read_text()
    assert "dof" not in text and "gain_k" not in text and "gain_U" not in text  # as such a record was written
    cfg.activate(tmp_path / "rig.toml", name)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no warning of its own: its keys were all a record held then
        loaded = cfg.load_rig(tmp_path / "rig.toml").record
    g = loaded.loads["strain"]
    assert g.gain_u == u and g.dof is None and g.gain_k is None and g.gain_U is None
    shown = orbitrig_here("calibrate", "show", "--config", str(tmp_path / "rig.toml"))
    assert shown.returncode == 0, shown.stderr
    assert (
        "\n# [loads.strain] u alone (k = 1; written before records held dof and U): its fit's 8 degrees of "
        "freedom make U = 2 u cover 91.9 %, Student's t (k 2.37) 95.45 %\n" in shown.stdout
    ), shown.stdout
    assert (
        "\n# [probes.x_a] u alone (k = 1; written before records held dof and U): its fit's 3 degrees" in shown.stdout
    )
    assert "cover 86.1 %, Student's t (k 3.31) 95.45 %\n" in shown.stdout
