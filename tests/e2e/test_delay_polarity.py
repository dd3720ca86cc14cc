"""A force channel read inverted (rig.toml ``gain = -0.1`` for fx_piezo and fx_strain against the
simulator's +0.1: as a load cell mounted reversed) is corrected once, by its gains, never also as
a 180 degree lag.

Real parts: `orbitrig calibrate loads` and `calibrate delay` on the simulator's clean scenario
(its strain gauges: +1.8 % gain, 0.3 deg lag; the piezo channels none), then `orbitrig sweep
--sim` at the paper's operating point, each a subprocess. The loads step's G carries the sign
(G_xx about -1); the delay step records the 0.3 deg lag, not 180.3; the sweep's K then has the
simulator's sign and value for both load measuring systems (before the fix both came out about
-K, and their comparison could not see it). Then the parts below the command: the delay fit's
phase wrapped into [-pi, pi) (a fit at -180.0006 deg once failed the step with a traceback) and
a record written before the fix (phase_deg near +-180) applied by the sweep's corrections.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from orbitrig.config import ChannelDelay, load_rig, read_record, rig_from_text
from orbitrig.run.corrections import Corrections
from orbitrig.store.reader import read_run
from reduction.calibration import fit_delay
from reduction.errors import ReductionError
from support.cli_helpers import orbitrig
from support.e2e_sweep import MATRIX
from support.paths import ROOT
from support.rig_configs import patient_rig_config

pytestmark = pytest.mark.timeout(600)
SPEEDUP = "40"  # the sweep's default: the patient drive link's 10 s watchdog holds with both cores busy
SCENARIO = ("--sim-config", "clean")
REVERSED = ("fx_piezo", "fx_strain")
STRAIN_LAG_DEG = 0.3  # config/sim/clean.toml: the strain gauges' constant lag
RATIOS = [0.363, 0.569, 0.871, 1.139]  # four of the paper's Table 1 Omega/omega


def reversed_lab(folder: Path) -> Path:
    """The shipped rig.toml (a patient drive link) and its records in `folder`, fx_piezo and
    fx_strain read with gain -0.1 (the simulator's sensors give +0.1): their readings inverted."""
    rig = patient_rig_config(folder)
    shutil.copytree(ROOT / "config/calibration", folder / "calibration")
    text = rig.read_text()
    for name in REVERSED:
        text, n = re.subn(rf'(name = "{name}"\n(?:[^\[\n].*\n)*?gain = )0\.1\n', r"\g<1>-0.1\n", text, count=1)
        assert n == 1, name
    rig.write_text(text)
    return rig


def step(rig: Path, *args: str):
    p = orbitrig("calibrate", *args, "--sim", *SCENARIO, "--config", str(rig), "--speedup", SPEEDUP, timeout=240)
    assert p.returncode == 0 and "Traceback" not in p.stderr, p.stdout + p.stderr
    return p


def test_a_reversed_force_channel_is_corrected_once_after_loads_and_delay(tmp_path):
    rig = reversed_lab(tmp_path / "lab")
    said = step(rig, "loads").stdout
    number, u = r"-?\d\.\d{5}", r"[0-9.e-]+"  # the gains to 5 decimals, their u to 2 digits, unquoted
    row, u_row = rf"\[{number}, {number}\]", rf"\[{u}, {u}\]"
    expanded = rf"; U \[{u_row}, {u_row}\], k 2\.37, dof 8"  # Student's t at the fit's 8 dof (exact loads)
    for lms in ("piezo", "strain"):
        assert re.search(
            rf"^{lms}: gain matrix \[{row}, {row}\] \(u \[{u_row}, {u_row}\]{expanded}\), residual ", said, re.M
        ), said
    loads, _ = read_record(tmp_path / "lab/calibration", load_rig(rig).calibration_record)
    assert loads.loads["piezo"].matrix[0, 0] == pytest.approx(-1.0, abs=2e-3)  # the sign is G's
    assert loads.loads["strain"].matrix[0, 0] == pytest.approx(-1 / 1.018, abs=2e-3)
    p = step(rig, "delay")
    delay, _ = read_record(tmp_path / "lab/calibration", load_rig(rig).calibration_record)
    # the lag apart from the sign: the fits' standard uncertainty is about 0.002 deg here
    for lms, lag in (("piezo", 0.0), ("strain", STRAIN_LAG_DEG)):
        for ax in ("fx", "fy"):
            assert delay.delay[f"{ax}_{lms}"].phase_deg == pytest.approx(lag, abs=0.05), (ax, lms, delay.delay)
    u, k = r"\(u [0-9.e-]+, U [0-9.e-]+", r"; k 3\.31, dof 3\)"  # 5 speeds: Student's t at the line's 3 dof
    lag = rf"lags the probes by -?\d+\.\d{{4}} deg {u}\) [+-] \d+\.\d{{2}} µs {u}{k}$"
    assert len(re.findall(rf"^f[xy]_(piezo|strain): {lag}", p.stdout, re.M)) == 4, p.stdout  # never "+ -0.05 µs"
    for name in REVERSED:  # the record's step says what it saw
        assert f"{name} reads the reference inverted" in p.stderr, p.stderr
    assert "fy_piezo reads the reference inverted" not in p.stderr

    (tmp_path / "m.toml").write_text(MATRIX.format(ratios=RATIOS))
    out = tmp_path / "run"
    args = ("--matrix", str(tmp_path / "m.toml"), "--out", str(out), "--config", str(rig), "--speedup", SPEEDUP)
    s = orbitrig("sweep", "--sim", *SCENARIO, *args, timeout=300)
    assert s.returncode == 0, s.stdout + s.stderr
    point = read_run(out).complete_points[0]
    k_true = np.asarray(point.truth["K0"])  # the constant K best fitting the simulator's Z
    for lms in ("piezo", "strain"):
        k = point.identification(lms, "kcd11", "none").result["coefficients"]
        # the right sign and value: within 2 % of the largest true entry (seen 0.0-0.4 % on 4
        # frequencies; the expanded uncertainty is about 2.5 %); the defect gave -K, 200 % off
        for key, true in (("Kxx", k_true[0, 0]), ("Kyy", k_true[1, 1])):
            assert k[key] > 0 and abs(k[key] - true) < 0.02 * np.max(np.abs(k_true)), (lms, key, k[key], true)


def test_the_fitted_phase_is_wrapped_and_an_inversion_is_a_sign_not_a_lag():
    f = np.array([5.0, 10.0, 15.0, 20.0, 25.0])
    # an inverted channel lagging by nothing: the fit landed just below -180 deg and the
    # record refused it (ChannelDelay: phase_deg in [-180, 180])
    fit = fit_delay(f, np.full(5, -np.pi - 1e-5))
    assert -np.pi <= fit.phase < np.pi and fit.phase == pytest.approx(np.pi - 1e-5, abs=1e-12)
    ChannelDelay(phase_deg=float(np.degrees(fit.phase)), delay_us=fit.delay * 1e6)
    assert fit.polarity == -1 and fit.lag == pytest.approx(-1e-5, abs=1e-12)
    lagging = fit_delay(f, np.full(5, np.pi + np.radians(0.3)))  # inverted, lagging 0.3 deg
    assert lagging.polarity == -1 and np.degrees(lagging.lag) == pytest.approx(0.3, abs=1e-9)
    plain = fit_delay(f, np.radians(0.3) + 2 * np.pi * f * 20e-6)
    assert plain.polarity == 1 and np.degrees(plain.lag) == pytest.approx(0.3, abs=1e-9)
    with pytest.raises(ReductionError, match="finite"):  # a channel that read nothing: no NaN record
        fit_delay(f, np.array([0.1, np.nan, 0.1, 0.1, 0.1]))


OLD_RECORD = """date = "2026-12-02T13:47:31.944Z"
operator = "ada"
rig = "double-spool rig"
step = "delay"
previous = "2026-12-02T134713Z-loads"
software = "orbitrig 0.1.0"

[loads.strain]
gain = [[-0.98237, 0.0], [0.0, 0.98225]]
gain_u = [[3.6e-05, 3.4e-05], [3.6e-05, 3.4e-05]]
offset_n = [0.0, 0.0]
residual_n = 0.03
loads = 7

[delay.fx_strain]
phase_deg = -179.6997478
delay_us = 0.0

[delay.fy_strain]
phase_deg = 0.3016512565
delay_us = 0.0
"""


def test_a_record_written_before_the_fix_is_not_applied_twice(tmp_path):
    """The audit's record: the strain gauges' fx inverted, its G_xx -0.982 and, from the delay
    step, phase_deg -179.70 (the 0.3 deg lag plus the inversion). The sweep's corrections turn
    the channel by the lag alone: the journal's force comes back with its sign."""
    rig = reversed_lab(tmp_path / "lab")
    text = re.sub(r"(?m)^calibration_record = .*$", 'calibration_record = "2026-12-02T134731Z-delay"', rig.read_text())
    corr = Corrections.of_rig(rig_from_text(text, str(rig), OLD_RECORD))
    orbit = 2 * np.pi * np.array([5.0, 10.0, 20.0])
    force = np.array([1000.0 + 200j, -300.0 + 900j, 50.0 - 700j])  # the journal's fx, N
    lag = np.exp(-1j * np.radians(0.3))
    read_x = -force * 1.018 * lag  # inverted (rig.toml -0.1), reading 1.8 % high, 0.3 deg late
    fx, fy = corr.forces("strain", read_x, np.zeros(3, dtype=complex), orbit)
    assert np.allclose(fx, force, rtol=1e-3), (fx, force)
