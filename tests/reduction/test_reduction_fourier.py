"""Phasors of angle-sampled signals: q(theta) = mean + Re(q_bar e^{i h theta})."""

from __future__ import annotations

import numpy as np
import pytest

from reduction.errors import ReductionError
from reduction.fourier import harmonic_fit, phasor


def signal(theta, q_bar, mean=0.0, h=1):
    return mean + np.real(q_bar * np.exp(1j * h * theta))


def test_uniform_full_circle_equals_the_dft_formula():
    rng = np.random.default_rng(0)
    theta = 2 * np.pi * np.arange(45) / 45
    q = rng.standard_normal(45)
    expected = 2 / 45 * np.sum(q * np.exp(-1j * theta))
    assert phasor(q, theta) == pytest.approx(expected, rel=1e-12, abs=1e-12)


def test_multiplexed_slots_need_no_phase_correction():
    # 8 channels sampled one slot apart: channel c at slots c, c+8, c+16, ... of a 360-slot disk
    slots = np.arange(0, 360, 8)[None, :] + np.arange(8)[:, None]  # (8, 45)
    theta = 2 * np.pi * slots / 360
    true = (np.arange(8) + 1) * np.exp(1j * np.linspace(0, 3, 8))
    q = signal(theta, true[:, None], mean=0.5 * np.arange(8)[:, None])
    fit = harmonic_fit(q, theta)
    np.testing.assert_allclose(fit.phasor, true, rtol=1e-12)
    np.testing.assert_allclose(fit.mean, 0.5 * np.arange(8), atol=1e-12)
    assert np.all(fit.rms_residual < 1e-12)


def test_arbitrary_angles_harmonic_and_mean():
    rng = np.random.default_rng(1)
    theta = np.sort(rng.uniform(0, 2 * np.pi, 30))  # irregular, not a full period grid
    q = 3.0 + signal(theta, 2 - 1j)
    assert phasor(q, theta) == pytest.approx(2 - 1j, rel=1e-12)
    q2 = 3.0 + signal(theta, 0.4 + 0.7j, h=2)
    fit = harmonic_fit(q2, theta, harmonic=2)
    assert fit.phasor == pytest.approx(0.4 + 0.7j, rel=1e-12)
    assert fit.mean == pytest.approx(3.0, rel=1e-12)


def test_vectorised_over_records_and_channels_with_axis():
    slots = np.arange(0, 360, 8)[None, :] + np.arange(4)[:, None]  # (4 channels, 45)
    theta = 2 * np.pi * slots / 360
    rng = np.random.default_rng(2)
    true = rng.standard_normal((10, 4)) + 1j * rng.standard_normal((10, 4))  # 10 records
    q = signal(theta[None], true[..., None])  # (10, 4, 45)
    np.testing.assert_allclose(phasor(q, theta), true, rtol=1e-12)
    # samples first: axis=0, angles 1-D along that axis
    th1 = 2 * np.pi * np.arange(45) / 45
    q0 = signal(th1[:, None, None], true[None])  # (45, 10, 4)
    np.testing.assert_allclose(phasor(q0, th1, axis=0), true, rtol=1e-12)


def test_angles_that_cannot_resolve_the_harmonic_are_refused():
    with pytest.raises(ReductionError, match="cannot resolve"):
        phasor(np.ones(4), np.zeros(4))
    with pytest.raises(ReductionError):
        phasor(np.ones(10), np.zeros(9))


@pytest.mark.parametrize(
    "samples, theta, says",
    [
        (np.where(np.arange(45) == 3, np.nan, 1.0), 1.0, "samples contain a non-finite"),
        (np.where(np.arange(45) == 3, np.inf, 1.0), 1.0, "samples contain a non-finite"),
        (np.ones(45), np.where(np.arange(45) == 3, np.nan, 1.0), "theta contains a non-finite"),
        (np.zeros(0), np.zeros(45), "no samples"),
    ],
)
def test_non_finite_or_missing_samples_are_refused_not_fitted_to_nan(samples, theta, says):
    """A NaN or inf sample (or angle) made every phasor of the fit NaN, silently; no samples
    at all was numpy's LinAlgError. Both are ReductionErrors that say what is wrong."""
    angles = 2 * np.pi * np.arange(45) / 45 * theta
    with pytest.raises(ReductionError, match=says):
        harmonic_fit(samples, angles[: samples.size])


from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402


@settings(max_examples=60, deadline=None)
@given(
    slots=st.lists(st.integers(0, 359), min_size=3, max_size=60, unique=True),
    re=st.floats(-1e3, 1e3),
    im=st.floats(-1e3, 1e3),
    mean=st.floats(-1e3, 1e3),
    harmonic=st.integers(1, 3),
)
def test_any_well_spread_slots_recover_the_phasor(slots, re, im, mean, harmonic):
    theta = 2 * np.pi * np.array(slots) / 360
    phases = np.exp(1j * harmonic * theta)
    basis = np.stack([np.ones_like(theta), phases.real, phases.imag], axis=1)
    try:
        fit = harmonic_fit(signal(theta, re + 1j * im, mean, harmonic), theta, harmonic)
    except ReductionError:
        # refused only for angles that nearly cannot resolve the harmonic (e.g. 3 slots 1 deg apart)
        assert np.linalg.cond(basis) > 1e3
        return
    scale = 1e-9 * (abs(re) + abs(im) + abs(mean) + 1)
    assert abs(fit.phasor - (re + 1j * im)) < scale * np.linalg.cond(basis)
    assert abs(fit.mean - mean) < scale * np.linalg.cond(basis)
