"""Coherence (paper Eq. 17, 18) from per-record phasors."""

from __future__ import annotations

import numpy as np
import pytest

from reduction.coherence import coherence, orbit_coherences
from reduction.errors import ReductionError


def test_noise_free_records_are_fully_coherent():
    rng = np.random.default_rng(0)
    x = np.exp(1j * rng.uniform(0, 2 * np.pi, 50))  # any record-to-record phase
    f = (3 - 2j) * x
    assert coherence(x, f) == pytest.approx(1.0, abs=1e-12)


def test_output_noise_gives_signal_over_total_power():
    rng = np.random.default_rng(1)
    n_d, s2, n2 = 20000, 4.0, 1.0  # signal power 4, complex noise power 1 -> 0.8
    x = np.ones(n_d, dtype=complex)
    f = 2.0 * x + np.sqrt(n2 / 2) * (rng.standard_normal(n_d) + 1j * rng.standard_normal(n_d))
    assert coherence(x, f) == pytest.approx(s2 / (s2 + n2), abs=0.01)


def test_vectorised_over_frequencies_and_the_table_order():
    rng = np.random.default_rng(2)
    n_d, n_freq = 30, 5
    x = np.exp(1j * rng.uniform(0, 6, (n_d, n_freq)))
    y = -1j * x
    fx = 2 * x + 0.5 * (rng.standard_normal((n_d, n_freq)) + 1j * rng.standard_normal((n_d, n_freq)))
    fy = 3 * y  # noise-free
    g = orbit_coherences(x, y, fx, fy)  # records along axis 0
    assert g.shape == (n_freq, 4)
    np.testing.assert_allclose(g[:, 2:], 1.0, atol=1e-12)  # xfy, yfy
    np.testing.assert_allclose(g[:, 0], g[:, 1], atol=1e-12)  # xfx == yfx on a circle
    assert np.all(g[:, 0] < 0.99)
    # records along another axis
    np.testing.assert_allclose(coherence(x.T, fx.T, axis=1), g[:, 0], rtol=1e-12)


def test_zero_power_gives_nan():
    assert np.isnan(coherence(np.zeros(3), np.ones(3)))


def test_a_non_finite_record_is_refused():
    """A NaN record gave a NaN coherence that only the orbit table caught, later and elsewhere."""
    with pytest.raises(ReductionError, match="not finite"):
        coherence(np.array([1.0, np.nan, 1.0]), np.ones(3))
    with pytest.raises(ReductionError, match="not finite"):
        orbit_coherences(np.ones(3), np.ones(3), np.array([1.0, 1.0, np.inf]), np.ones(3))
