"""The probes' reference (the micrometer of `calibrate probes`) counts once in the sweep's
uncertainty budget.

Real parts: `orbitrig calibrate loads` (exact loads on the simulator: the force channels' gain
uncertainty becomes tiny), `calibrate probes --reference-u-pct 0.5`, then `orbitrig sweep --sim`
at the paper's operating point (clean scenario), each a subprocess. A 0.5 % error of the
reference scales every displacement, so K by 0.5 % (reduction/systematic.py's hand check, for the
displacements): the expanded uncertainty of Kxx is then k 0.5 % |Kxx|, plus what little else
the budget holds. Counted twice (each probe's gain_pct and probe_sensitivity_pct, added as
independent errors) it was sqrt(2) times that.
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from orbitrig.config import load_rig, read_record
from orbitrig.store.reader import read_run
from support.cli_helpers import orbitrig
from support.e2e_sweep import MATRIX
from support.paths import ROOT
from support.rig_configs import patient_rig_config

pytestmark = pytest.mark.timeout(600)
SPEEDUP = "40"  # the sweep's default: the patient drive link's 10 s watchdog holds with both cores busy
SCENARIO = ("--sim-config", "clean")
U_REF = 0.005  # --reference-u-pct 0.5
RATIOS = [0.363, 0.569, 0.871, 1.139]  # four of the paper's Table 1 Omega/omega


def test_the_micrometer_counts_once_in_the_sweeps_budget(tmp_path):
    rig = patient_rig_config(tmp_path / "lab")
    shutil.copytree(ROOT / "config/calibration", tmp_path / "lab/calibration")
    common = ("--sim", *SCENARIO, "--config", str(rig), "--speedup", SPEEDUP)
    for args in (("loads",), ("probes", "--reference-u-pct", "0.5")):
        p = orbitrig("calibrate", *args, *common, timeout=240)
        assert p.returncode == 0, p.stdout + p.stderr
    rec, _ = read_record(tmp_path / "lab/calibration", load_rig(rig).calibration_record)
    assert rec.uncertainty.probe_sensitivity_pct == pytest.approx(0.5)  # the reference, once: here
    for p, g in rec.probes.items():
        assert g.gain_u / g.gain == pytest.approx(U_REF, rel=1e-3)  # the gain's whole uncertainty
        # the fit's own part only (seen about 0.001 %; the steps are linear to 0.002 %)
        assert rec.uncertainty.channel(p).gain_pct < 0.01, (p, rec.uncertainty)

    (tmp_path / "m.toml").write_text(MATRIX.format(ratios=RATIOS))
    out = tmp_path / "run"
    args = ("--matrix", str(tmp_path / "m.toml"), "--out", str(out), "--config", str(rig), "--speedup", SPEEDUP)
    s = orbitrig("sweep", "--sim", *SCENARIO, *args, timeout=300)
    assert s.returncode == 0, s.stdout + s.stderr
    result = read_run(out).complete_points[0].identification("piezo", "kcd11", "none").result
    u = result["uncertainty"]
    source = dict(zip(u["sources"], u["source_std"]))
    for axis in ("x", "y"):  # the budget's probe errors, each a gain of the displacements: the reference once
        total = np.hypot(source[f"{axis}.gain"], source[f"{axis}.sensitivity"])
        assert total == pytest.approx(U_REF, rel=1e-3), source
    k, expanded = result["coefficients"]["Kxx"], result["expanded_uncertainty"]
    expected = expanded["k"] * U_REF * abs(k)
    ratio = expanded["values"]["Kxx"] / expected
    # the rest of the budget adds in quadrature: the fit's statistics (about 0.03 % of K), the
    # loads fit's gains (0.004 %), the shipped phases and delays (0.05 deg, 10-20 us: a few
    # 0.01 % of K at these speeds), so the ratio is 1.00-1.01 (seen 1.002); twice: 1.414
    assert 0.995 < ratio < 1.03, (ratio, expanded["values"]["Kxx"], expected, source)
