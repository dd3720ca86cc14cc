"""The calibration steps' reductions on the simulator's own signals (sim.revolutions: the chain,
the disturbances and the slot-edge sampling of the A/D board, without transport), against what the
scenario injects.

- `loads`: gain errors of both load measuring systems and of the board, and board offsets that
  rig.toml does not know, drawn per seed; `reduction.calibration.fit_gain_matrix` of seven static
  loads read as the step reads them (the static part of an average, int16 counts through rig.toml's
  gain) finds the true matrix within its stated standard uncertainty as a t with the fit's 8
  degrees of freedom scatters.
- `runout`: the probe tracks' runout read at a slow roll (ratio 1) is referenced to slot 0 (the
  trigger): Re(sum_h R_h e^{i h theta}) gives the slow roll's samples back; the y probe's track
  reads 90 degrees behind the x probe's. Subtracted from a block at an orbit ratio off the
  harmonics, forward and backward whirl alike (the spin turns |omega / Omega| times per board
  revolution: the slot order follows time whatever the orbit's direction), it leaves nothing; the
  conjugate record (the phase convention reversed) or the signed ratio for a backward block leave
  the whole runout."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from orbitrig.run.calibration_measure import runout_of
from reduction.calibration import fit_gain_matrix
from reduction.fourier import phasor
from reduction.runout import remove_runout, runout_basis
from sim.scenario_files import load_sim_config
from sim.physics import RigPhysics
from sim.revolutions import simulate_revolutions
from support.paths import ROOT

RPM = 2 * math.pi / 60
SLOT = 2 * math.pi / 360
#: the loads step's seven loads (N): none, +-x, +-y, the two diagonals
LOADS = 1000.0 * np.array([[0, 0], [1, 0], [-1, 0], [0, 1], [0, -1], [0.7071, 0.7071], [-0.7071, -0.7071]])
FORCES = ("fx_piezo", "fy_piezo", "fx_strain", "fy_strain")
PROBES = ("x_a", "y_a", "x_b", "y_b")
RIG_GAIN = 0.1  # rig.toml's force channels: N per count, offset 0


def _slow_roll(seed: int) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], dict[str, np.ndarray]]:
    """The paper scenario with drawn errors: ({lms: (7, 2) readings (N)}, {lms: true G}, {lms: true b})."""
    rng = np.random.default_rng(100 + seed)
    base = load_sim_config(ROOT / "config/sim.toml")
    e_piezo, e_strain = rng.uniform(-0.03, 0.03, 2)
    lms = dataclasses.replace(base.lms, piezo_gain_error=e_piezo, strain_gain_error=e_strain)
    cfg = dataclasses.replace(base, seed=seed, lms=lms)
    physics = RigPhysics(cfg)
    physics.set_manual(orbit_radius=0.0, static_eccentricity=0.0)
    idx = [list(cfg.adc.channels).index(n) for n in FORCES]
    board_gain = np.array(cfg.adc.gains)[idx] * (1 + rng.uniform(-0.02, 0.02, 4))
    board_offset = rng.uniform(-50.0, 50.0, 4)  # N
    readings = []
    for load in LOADS:
        physics.apply_load(*load)
        _, v = simulate_revolutions(physics, 300 * RPM, 300 * RPM, 50)
        counts = np.round((v[:, idx, :] - board_offset[None, :, None]) / board_gain[None, :, None])
        readings.append((counts * RIG_GAIN).mean(axis=(0, 2)))
    r = np.array(readings)
    sens = np.array([(1 + physics.chains[k].gain) * RIG_GAIN / board_gain[i] for i, k in enumerate(idx)])
    out = {"piezo": r[:, :2], "strain": r[:, 2:]}
    truth = {"piezo": np.diag(1 / sens[:2]), "strain": np.diag(1 / sens[2:])}
    shift = board_offset * RIG_GAIN / board_gain  # what the readings lack of the load (N)
    offsets = {lms: truth[lms] @ shift[i : i + 2] for lms, i in (("piezo", 0), ("strain", 2))}
    assert (
        abs(truth["piezo"][0, 0] * (1 + e_piezo) - 1) < 0.03 and abs(truth["strain"][0, 0] * (1 + e_strain) - 1) < 0.03
    )
    return out, truth, offsets


def test_the_loads_fit_finds_injected_gain_and_offset_errors_within_its_stated_uncertainty():
    z, worst = [], 0.0
    for seed in range(1, 13):
        readings, truth, offsets = _slow_roll(seed)
        for lms, r in readings.items():
            fit = fit_gain_matrix(LOADS, r, 0.0)
            z.extend(((fit.gain - truth[lms]) / fit.gain_u).ravel())
            worst = max(worst, float(np.max(np.abs(fit.gain - truth[lms]))))
            # the board's offset (up to 50 N, unknown to rig.toml) is b, within the residuals' scatter
            assert np.all(np.abs(fit.offset - offsets[lms]) < 3 * fit.residual_rms)
    z = np.asarray(z)
    assert worst < 3e-3  # 12 seeds x 2 systems: the fit within 0.3 % of the true matrix
    # u is a standard uncertainty of 8 degrees of freedom: z scatters as t(8), rms sqrt(8/6) = 1.15
    assert 0.8 < float(np.sqrt(np.mean(z**2))) < 1.5 and np.mean(np.abs(z) < 2) > 0.85, z


@pytest.fixture(scope="module")
def runout_only():
    """The clean scenario with runout alone on the probes (no noise), no orbit: (physics, probe indices)."""
    base = load_sim_config(ROOT / "config/sim/clean.toml")
    quiet = dict(probe_white=0.0, runout=(1e-6, 0.4e-6), bearing_probe=0.0, line_probe=0.0, speed_ripple=0.0)
    physics = RigPhysics(dataclasses.replace(base, noise=dataclasses.replace(base.noise, **quiet)))
    physics.set_manual(orbit_radius=0.0, static_eccentricity=0.0)
    return physics, [list(base.adc.channels).index(p) for p in PROBES]


def test_runout_is_referenced_to_slot_0_and_taken_out_of_forward_and_backward_blocks(runout_only):
    physics, idx = runout_only
    slots, v = simulate_revolutions(physics, 100 * RPM, 100 * RPM, 8)  # the slow roll
    theta = slots * SLOT
    R = np.array([runout_of(v[:, k, :], 1.0, 0.0, theta[k])[0] for k in idx])  # (4, 2), m
    assert np.abs(R[:, 0]) == pytest.approx(1e-6, rel=1e-6) and np.abs(R[:, 1]) == pytest.approx(0.4e-6, rel=1e-6)
    for p, k in enumerate(idx):  # Re(R1 e^{i theta} + R2 e^{2 i theta}) is what the probe read at theta
        model = np.real(R[p, 0] * np.exp(1j * theta[k]) + R[p, 1] * np.exp(2j * theta[k]))
        assert np.max(np.abs(v[:, k, :] - model)) < 1e-12
    assert np.angle(R[1, 0] / R[0, 0]) == pytest.approx(-math.pi / 2, abs=1e-6)  # y_a 90 deg behind x_a
    spin = 1000 * RPM
    for direction in (+1, -1):
        orbit = direction * 0.471 * spin
        sl, w = simulate_revolutions(physics, spin, orbit, 12, t0=0.37)
        th = (sl * SLOT)[idx]
        rec = np.array([[phasor(w[n, k, :], t) for k, t in zip(idx, th)] for n in range(12)])
        revs = np.arange(12)
        assert np.max(np.abs(rec.mean(axis=0))) > 20e-9  # 1 µm of runout leaks ~28 nm into the mean
        clean = remove_runout(rec, R, runout_basis(th, spin / abs(orbit), revs, 2))
        assert np.max(np.abs(clean)) < 1e-12
        assert np.max(np.abs(remove_runout(rec, np.conj(R), runout_basis(th, spin / abs(orbit), revs, 2)))) > 100e-9
        if direction < 0:  # the spin turns +|omega/Omega| per board revolution in a backward block too
            assert np.max(np.abs(remove_runout(rec, R, runout_basis(th, spin / orbit, revs, 2)))) > 100e-9
