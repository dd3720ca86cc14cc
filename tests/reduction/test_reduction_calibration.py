"""reduction.calibration (gain matrix from static loads, phase and delay from a reference) and
reduction.runout (the probes' runout in a block's phasors): known answers, Monte Carlo coverage
of the stated uncertainties, refusals."""

from __future__ import annotations

import numpy as np
import pytest

from reduction.calibration import correct_forces, correct_lag, fit_delay, fit_gain_matrix, fit_probe, static_loads
from reduction.errors import ReductionError
from reduction.fourier import phasor
from reduction.runout import fit_spin_phase, remove_runout, runout_basis

G_TRUE = np.array([[0.982, 0.004], [-0.006, 0.991]])  # cross-axis terms included
OFFSET = np.array([3.0, -2.0])


def _readings(loads: np.ndarray, noise: float, rng) -> np.ndarray:
    """What a system with gain matrix G_TRUE reads: r = G^-1 (L - b) + noise (N)."""
    return (np.linalg.solve(G_TRUE, (loads - OFFSET).T)).T + rng.normal(0, noise, loads.shape)


def test_exact_readings_give_the_gain_matrix_and_offset():
    loads = static_loads(500.0)
    fit = fit_gain_matrix(loads, _readings(loads, 0.0, np.random.default_rng(0)), 0.0)
    assert np.allclose(fit.gain, G_TRUE, atol=1e-12) and np.allclose(fit.offset, OFFSET, atol=1e-9)
    assert fit.residual_rms < 1e-9 and fit.dof == 8
    fx, fy = correct_forces(fit.gain, *np.linalg.solve(G_TRUE, np.array([[100.0], [50.0]])))
    assert np.allclose([fx[0], fy[0]], [100.0, 50.0])


def test_gain_uncertainty_covers_the_error_about_95_percent_at_k2():
    rng = np.random.default_rng(7)
    loads = np.vstack([static_loads(500.0)] * 2)  # 14 loads: 22 degrees of freedom
    inside, trials = 0, 400
    for _ in range(trials):
        fit = fit_gain_matrix(loads, _readings(loads, 2.0, rng), 0.0)
        inside += int(np.sum(np.abs(fit.gain - G_TRUE) <= 2 * fit.gain_u))
    share = inside / (4 * trials)
    assert 0.92 <= share <= 0.975, share  # 95 % (a t distribution with 22 dof: 94.2 %)


def test_reference_uncertainty_adds_to_every_entry():
    loads = static_loads(500.0)
    r = _readings(loads, 0.0, np.random.default_rng(1))
    fit = fit_gain_matrix(loads, r, 0.001)
    assert np.allclose(fit.gain_u, 0.001 * np.abs(G_TRUE), rtol=1e-6)
    assert np.allclose(fit.relative_gain_u(), np.sqrt(np.sum((0.001 * G_TRUE) ** 2, 1)) / np.abs(np.diag(G_TRUE)))


@pytest.mark.parametrize(
    "loads, why",
    [(static_loads(500.0)[:3], "at least 4"), (np.array([[0, 0], [1, 0], [2, 0], [3, 0.0]]), "span both axes")],
)
def test_too_few_or_one_axis_loads_are_refused(loads, why):
    with pytest.raises(ReductionError, match=why):
        fit_gain_matrix(loads, loads * 1.01, 0.0)


def test_phase_and_delay_fit_and_correction():
    f = np.array([5.0, 10.0, 15.0, 20.0, 25.0])
    phase, delay = np.radians(0.3), 20e-6
    fit = fit_delay(f, phase + 2 * np.pi * f * delay)
    assert fit.phase == pytest.approx(phase, abs=1e-12) and fit.delay == pytest.approx(delay, rel=1e-9)
    orbit = 2 * np.pi * f
    lagging = np.exp(-1j * (phase + orbit * delay))
    assert np.allclose(correct_lag(lagging, orbit, fit.phase, fit.delay), 1.0)
    with pytest.raises(ReductionError, match="3 or more"):
        fit_delay(f[:2], f[:2])


def test_a_delay_that_wraps_is_fitted_whatever_order_the_speeds_were_run_in():
    """20 ms lags 7.5 rad at 60 Hz: the wrapped lags unwrap only along ascending frequency.
    Run in the order 40, 5, 25, 60, 10 Hz they read phase 1.40 rad and delay -1.7 ms."""
    f = np.array([40.0, 5.0, 25.0, 60.0, 10.0])
    phase, delay = 0.1, 0.02
    fit = fit_delay(f, np.angle(np.exp(1j * (phase + 2 * np.pi * f * delay))))
    assert fit.phase == pytest.approx(phase, abs=1e-9) and fit.delay == pytest.approx(delay, rel=1e-9)
    assert fit.residual_rms < 1e-9


def _probe_revolutions(rho: float, runout: np.ndarray, phi0: float, noise: float, rng):
    """Per-revolution probe phasors (N, 4) of an orbit d plus runout locked to the spin angle,
    sampled as the board does (sequential mode, 8 channels, probes on channels 4..7)."""
    theta = np.array([2 * np.pi * (np.arange(45) * 8 + k) / 360 for k in range(4, 8)])
    d = np.array([2.4e-6, -2.4e-6j, 2.3e-6, -2.5e-6j])
    revs = np.delete(np.arange(17, 67), [10, 11])  # two dropped revolutions
    rec = []
    for n in revs:
        psi = phi0 + 2 * np.pi * rho * (n - revs[0]) + rho * theta
        v = np.real(d[:, None] * np.exp(1j * theta)) + np.real(
            runout[:, :1] * np.exp(1j * psi) + runout[:, 1:] * np.exp(2j * psi)
        )
        rec.append(phasor(v + rng.normal(0, noise, v.shape), theta))
    return np.array(rec), d, theta, revs


@pytest.mark.parametrize("ratio", [0.569, 1.041])
def test_runout_leaves_the_mean_exactly_once_its_spin_phase_is_fitted(ratio):
    rng = np.random.default_rng(3)
    runout = 1e-7 * np.exp(1j * rng.uniform(0, 2 * np.pi, (4, 2))) * np.array([1.0, 0.5])
    rec, d, theta, revs = _probe_revolutions(1 / ratio, runout, 1.234, 0.0, rng)
    assert np.max(np.abs(rec.mean(0) - d) / np.abs(d)) > 3e-4  # the runout leaks into the mean
    assert fit_spin_phase(rec, runout, theta, 1 / ratio, revs) == pytest.approx(1.234, abs=1e-5)
    clean = remove_runout(rec, runout, runout_basis(theta, 1 / ratio, revs, runout.shape[1]))
    assert np.max(np.abs(clean.mean(0) - d) / np.abs(d)) < 1e-8


def test_probe_gain_and_linearity():
    steps = np.linspace(-20e-6, 20e-6, 5)
    fit = fit_probe(steps, steps / 1.007 + 3e-7, 0.0)
    assert fit.gain == pytest.approx(1.007, rel=1e-9) and fit.offset == pytest.approx(-3e-7 * 1.007, rel=1e-6)
    assert fit.linearity < 1e-9 and fit.gain_u < 1e-9
    bent = fit_probe(steps, steps + 0.002 * steps**2 / 20e-6, 0.001)  # a bowed probe: 0.2 % of 20 um at the ends
    assert 1e-4 < bent.linearity < 1e-3 and bent.gain_u > 0.001 * bent.gain
    with pytest.raises(ReductionError, match="3 or more"):
        fit_probe(steps[:2], steps[:2], 0.0)
