"""`orbitrig calibrate runout --sim` on a scenario whose spin drive turns a fraction fast
(sim.config.DrivesConfig ``spin_speed_error``: the two spindles out of step, as on the rig, where
nothing locks them): the step fits the slip from the runout, turns each revolution back by it and
records it; the runout it records is the scenario's within its stated u (each amplitude within
3.5 u, the four probes' mean within 1.75 u), where the plain mean of the old step lost 2 % (1x) and
6 % (2x) at 0.1 % slip and 37 % and nearly all at 0.5 %. A slip beyond the 1 % the step corrects is
refused, naming it, no record written. Real parts: a subprocess, the simulator's drives over Modbus
TCP, its A/D board's frames."""

from __future__ import annotations

import re
import shutil

import numpy as np
import pytest

from orbitrig.config import load_rig, read_record
from support.cli_helpers import orbitrig
from support.paths import ROOT
from support.rig_configs import patient_rig_config

pytestmark = pytest.mark.timeout(120)
TRUTH = np.array([0.1e-6, 0.05e-6])  # clean.toml: the probe tracks' runout at 1x and 2x (chain off)


def _runout(tmp_path, error: float):
    """`calibrate runout --sim` (100 revolutions) on clean.toml with the spin drive ``error`` fast."""
    patient_rig_config(tmp_path)  # a link that holds with both cores busy
    shutil.copytree(ROOT / "config/calibration", tmp_path / "calibration")
    scenario = tmp_path / "slip.toml"
    scenario.write_text((ROOT / "config/sim/clean.toml").read_text() + f"\n[drives]\nspin_speed_error = {error}\n")
    rig = tmp_path / "rig.toml"
    args = ("calibrate", "runout", "--sim", "--sim-config", str(scenario), "--config", str(rig))
    return orbitrig(*args, "--revolutions", "100", "--speedup", "100"), rig


@pytest.mark.parametrize("error", [0.0, 0.001, 0.005])
def test_the_runout_of_a_slipping_slow_roll_is_recorded_within_its_u_with_the_slip(tmp_path, error):
    p, rig = _runout(tmp_path, error)
    assert p.returncode == 0, p.stderr
    record, _ = read_record(tmp_path / "calibration", load_rig(rig).calibration_record)
    runout = record.runout
    assert runout is not None and runout.slip_pct is not None and runout.slip_u_pct is not None
    # the slip's error scatters wider than its u (the speed ripple's slow phase is not in the
    # revolutions' scatter): rms 0.8, 1.2, 0.9 u at 0, 0.1, 0.5 % here (13 runs each), up to 1.5 u
    # in tests/reduction/test_runout_slip.py's seeds. 6 u (with the 2e-4 %: 4.2 sd at 1.5 u, 3e-5 a
    # check) where 4 u failed 5e-4 to 4e-3 of the runs; a slip not fitted (100 u at 0.1 %) or fitted
    # at the wrong harmonic still fails.
    assert runout.slip_pct == pytest.approx(error * 100, abs=6 * runout.slip_u_pct + 2e-4), p.stderr
    assert 0 < runout.slip_u_pct < 0.002  # 0.0008 % over 100 revolutions
    probes = ("x_a", "y_a", "x_b", "y_b")
    amps = np.abs([runout.phasors(q) for q in probes])
    u = runout.uncertainties(probes)
    assert u is not None and np.all(u < 1.5e-9)
    # u is the combined scatter of the complex mean (reduction.noise.phasor_uncertainty); an
    # amplitude takes its radial part alone, about u / sqrt(2) (measured: rms 0.74 u over 312
    # amplitudes of 13 runs). Each within 3.5 u (4.7 of its sd: 2e-6 a check), the four probes'
    # mean per harmonic within 1.75 u (4.7 of its sd again): 7e-5 a run of the three slips, where
    # 2 u on each amplitude failed about 1 run in 10. The step without the turn back: u 1.9 nm at
    # 0.1 % slip (its revolutions scatter by the turn), amplitudes 4.5 to 10 u low at 0.5 %.
    z = (amps - TRUTH) / u
    assert np.all(np.abs(z) < 3.5) and np.all(np.abs(z.mean(axis=0)) < 1.75), z
    assert f"spin slip against the orbit spindle {runout.slip_pct:+.4f} %" in p.stdout


def test_a_slip_beyond_what_the_step_corrects_is_refused_naming_it(tmp_path):
    before = sorted(p.name for p in (ROOT / "config/calibration").iterdir())
    p, _ = _runout(tmp_path, 0.02)
    assert p.returncode == 1 and "Traceback" not in p.stderr, p.stderr
    said = re.search(r"the spin slipped ([+-][\d.]+) % \(u ([\d.]+) %\)", p.stderr)
    assert said is not None and "beyond the 1 % the runout step corrects" in p.stderr, p.stderr
    slip, u = float(said[1]), float(said[2])
    assert slip == pytest.approx(2.0, abs=4 * u + 2e-3), p.stderr  # the fit's spread; the message's rounding
    assert "both drives stopped" in p.stderr
    assert sorted(p.name for p in (tmp_path / "calibration").iterdir()) == before  # no record written
