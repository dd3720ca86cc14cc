"""The slow roll's slip fitted from the runout itself (reduction.runout_slip) on the simulator's own
signals (sim.revolutions: the clean scenario's probes, their noise, speed ripple and the board's
slot-edge sampling): the spin a fraction ahead of the orbit spindle turns the runout's phase by
h 2 pi s per revolution, and the plain mean of 100 revolutions loses the 1x and the 2x; turned back
by the fitted slip the mean is the runout again, within its stated uncertainty."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from orbitrig.run.calibration_measure import SLIP_LIMIT, revolution_harmonics, runout_of, slip_refused
from reduction.noise import phasor_uncertainty
from reduction.runout_slip import NO_SCATTER, aligned, fit_slip
from sim.scenario_files import load_sim_config
from sim.physics import RigPhysics
from sim.revolutions import simulate_revolutions
from support.paths import ROOT

RPM = 2 * math.pi / 60
SLOT = 2 * math.pi / 360
PROBES = ("x_a", "y_a", "x_b", "y_b")


def _slow_roll(slip: float, seed: int = 1, n: int = 100) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """100 revolutions of the clean scenario at 100 rpm, the spin ``slip`` fast: ((4, 2, n) each
    revolution's 1x and 2x, (4, S) counts' angles, (4, n, S) the probes' values (m))."""
    base = load_sim_config(ROOT / "config/sim/clean.toml")
    physics = RigPhysics(dataclasses.replace(base, seed=seed))
    physics.set_manual(orbit_radius=0.0, static_eccentricity=0.0)
    idx = [list(base.adc.channels).index(p) for p in PROBES]
    slots, v = simulate_revolutions(physics, 100 * RPM * (1 + slip), 100 * RPM, n)
    theta = (slots * SLOT)[idx]
    values = np.stack([v[:, k, :] for k in idx])
    per_rev = np.stack([revolution_harmonics(values[p], 1.0, 0.0, theta[p]) for p in range(4)])
    return per_rev, theta, values


TRUTH = np.array([0.1e-6, 0.05e-6])  # clean.toml: the probe tracks' runout at 1x and 2x (chain off)


@pytest.mark.parametrize("slip", [0.001, 0.005])
def test_a_slipping_spin_is_fitted_and_turned_back_so_the_runout_holds_within_its_u(slip):
    per_rev, theta, values = _slow_roll(slip)
    plain = np.abs(per_rev.mean(axis=2))  # the old step's mean
    loss = 1 - plain / TRUTH
    if slip == 0.001:  # the audit's figures: 1x about 2 % low, 2x about 6 % low
        assert 0.005 < loss[:, 0].mean() < 0.03 and 0.04 < loss[:, 1].mean() < 0.08, loss
    else:  # 1x about 37 % low, the 2x almost gone
        assert 0.3 < loss[:, 0].mean() < 0.45 and loss[:, 1].min() > 0.9, loss
    fit = fit_slip(per_rev)
    assert fit.slip == pytest.approx(slip, abs=max(4 * fit.slip_u, 2e-5)) and 0 < fit.slip_u < 2e-5
    # as the step reads each probe (its counts through its gain): fitted at the slipped harmonics, turned back
    got = [runout_of(values[p] / 5e-9, 5e-9, 0.0, theta[p], fit.slip) for p in range(4)]
    h, u = np.abs([g[0] for g in got]), np.array([g[1] for g in got])
    assert np.all(np.abs(h - TRUTH) < 2 * u), (h - TRUTH) / u  # within U = 2u, every probe and harmonic
    assert np.all(u < 1.5e-9)  # the scatter is the noise's, not the slip's turn (0.6 nm per probe)
    # the board's harmonics turned back alone come within U as well; the slipped fit takes their leakage out
    turned = aligned(per_rev, fit.slip)
    assert np.all(np.abs(np.abs(turned.mean(axis=2)) - TRUTH) < 2 * phasor_uncertainty(turned, axis=2))
    assert slip_refused(fit) == ""


def test_without_slip_the_record_is_as_before_and_a_slip_beyond_the_limit_is_refused():
    per_rev, theta, values = _slow_roll(0.0)
    fit = fit_slip(per_rev)
    assert abs(fit.slip) < 4 * fit.slip_u + 1e-6
    before = per_rev.mean(axis=2)  # the old step's mean
    u = phasor_uncertainty(per_rev, axis=2)
    after = np.array([runout_of(values[p] / 5e-9, 5e-9, 0.0, theta[p], fit.slip)[0] for p in range(4)])
    assert np.all(np.abs(after - before) < 0.1 * u)  # within a tenth of its u: noise
    fast, _, _ = _slow_roll(0.02, n=20)
    far = fit_slip(fast)
    assert far.slip == pytest.approx(0.02, abs=2e-4)
    said = slip_refused(far)
    assert (
        said.startswith(f"the spin slipped {far.slip * 100:+.3f} % (u ")
        and f"beyond the {SLIP_LIMIT * 100:g} % " in said
    ), said
    assert "no record written" in said


def test_the_slips_stated_u_covers_its_error_over_seeds():
    """Monte Carlo: 16 seeds at 0.3 % slip (64 revolutions each); the error over the stated u
    scatters with rms below 2 (measured: 1.07; 1.21 at 0.1 %, 1.47 at 0.5 % over 100 revolutions) and its mean within 1.5 (the speed ripple's slow
    phase, which the per-revolution scatter does not count, is part of it)."""
    z = []
    for seed in range(16):
        per_rev, _, _ = _slow_roll(0.003, seed=seed, n=64)
        fit = fit_slip(per_rev)
        z.append((fit.slip - 0.003) / fit.slip_u)
    z = np.asarray(z)
    assert float(np.sqrt(np.mean(z**2))) < 2.0 and abs(float(np.mean(z))) < 1.5, z


def test_a_dead_probe_is_left_out_of_the_slip_and_with_all_dead_no_slip_is_fitted():
    """A probe reading exact zeros has no scatter: it once made the slip's u nil (0) for all."""
    per_rev, _, _ = _slow_roll(0.003, n=64)
    live = fit_slip(per_rev[1:])
    dead = per_rev.copy()
    dead[0] = 0.0  # x_a dead
    fit = fit_slip(dead)
    assert fit.slip_u == pytest.approx(live.slip_u, rel=1e-9) and 1e-6 < fit.slip_u < 1e-4  # before: 0
    assert fit.unfitted == ""
    assert fit.slip == pytest.approx(live.slip, abs=1e-12)
    assert abs(fit.slip - 0.003) < 4 * fit.slip_u
    none = fit_slip(np.zeros_like(per_rev))
    assert (none.slip, none.slip_u) == (0.0, math.inf)
    assert none.unfitted == NO_SCATTER and "dead probes" in none.unfitted
    short = fit_slip(per_rev[:, :, :2])
    assert (short.slip, short.slip_u, short.unfitted) == (0.0, math.inf, "fewer than 3 revolutions (2)")


def test_revolutions_left_out_of_a_block_are_placed_by_their_board_numbers():
    """A block's revolutions carry the board's numbers, with a gap where a damaged one was dropped:
    the slope is fitted against those numbers (counted as consecutive, a gap of 5 in 40 at 0.3 %
    put the slip 19 % off, 17 u)."""
    per_rev, _, _ = _slow_roll(0.003, n=45)
    keep = np.r_[0:20, 25:45]  # revolutions 20 to 24 dropped
    fit = fit_slip(per_rev[:, :, keep], revolutions=keep)
    assert abs(fit.slip - 0.003) < 4 * fit.slip_u and fit.slip_u < 4e-5, fit
    counted = fit_slip(per_rev[:, :, keep])  # the old reading: consecutive
    assert abs(counted.slip - 0.003) > 10 * counted.slip_u, counted


def test_a_block_without_spin_content_is_not_fitted():
    """Per-revolution phasors of noise alone (no runout, no spin tone): the coarse turn's phase
    of a mean in the noise is arbitrary, so no slip is fitted (u inf, NO_TONE), in every one of 300
    draws; before, each was 'fitted', 50 % off the ratio with a u of 1 %. A tone 30 standard errors
    out of the noise (about 5 times the noise in each revolution) is fitted, within 4 u of its slip,
    in every draw."""
    from reduction.runout_slip import NO_TONE, fit_slip

    rng = np.random.default_rng(11)
    n, slip = 40, 0.003
    k = np.arange(n)
    for _ in range(300):
        noise = rng.standard_normal((4, 2, n)) + 1j * rng.standard_normal((4, 2, n))
        fit = fit_slip(noise)
        assert fit.slip_u == np.inf and fit.unfitted == NO_TONE
        tone = 30.0 * np.sqrt(2.0 / n) * np.exp(2j * np.pi * slip * np.outer([1, 2], k))  # |mean| 30 standard errors
        fitted = fit_slip(noise + tone[None])
        assert np.isfinite(fitted.slip_u) and abs(fitted.slip - slip) < 4 * fitted.slip_u
