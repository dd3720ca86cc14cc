"""Monte Carlo checks with noisy synthetic data: standard errors, weighting, and the
attenuation bias of least squares with noisy displacements (removed by tls and iv)."""

from __future__ import annotations

import numpy as np
import pytest

from support.reduction_synthetic import (
    coherent_noise_tables,
    frequencies,
    keys_of,
    orbit_table,
    truth,
    with_force_noise,
    with_noise,
)
from reduction.identify import identify

TRUE = truth("kc8", {"K": (0,), "C": (0,)})
KEYS = list(keys_of(TRUE))
EXPECTED = np.array([keys_of(TRUE)[k] for k in KEYS])


def _run(tables, method, **kw):
    est, se = [], []
    for t in tables:
        r = identify(t, "kc8", "none", method, **kw)
        est.append([r.coefficients[k] for k in KEYS])
        se.append([r.std_errors[k] for k in KEYS])
    return np.array(est), np.array(se)


def test_reported_std_errors_match_the_spread_over_trials():
    rng = np.random.default_rng(11)
    clean = orbit_table(TRUE, frequencies(6))
    s = 0.01 * np.sqrt(np.mean(np.abs(clean.fx) ** 2))
    trials = [with_force_noise(clean, rng, s) for _ in range(400)]
    est, se = _run(trials, "ols")
    ratio = est.std(axis=0, ddof=1) / se.mean(axis=0)
    # 400 trials: the sample std is good to ~3.5 % (1 sigma); allow 4 sigma
    assert np.all(np.abs(ratio - 1) < 0.15), dict(zip(KEYS, ratio.round(3)))
    z = (est.mean(axis=0) - EXPECTED) / (est.std(axis=0, ddof=1) / np.sqrt(len(trials)))
    assert np.all(np.abs(z) < 4), dict(zip(KEYS, z.round(2)))  # unbiased


def test_coherence_weights_reduce_the_spread_and_keep_std_errors_honest():
    trials = coherent_noise_tables(TRUE, np.random.default_rng(12), 300)
    wls, wse = _run(trials, "wls")
    ols, _ = _run(trials, "ols")
    ratio = wls.std(axis=0, ddof=1) / wse.mean(axis=0)
    assert np.all(np.abs(ratio - 1) < 0.2), dict(zip(KEYS, ratio.round(3)))
    assert np.all(wls.std(axis=0) < 0.7 * ols.std(axis=0))


def test_tls_and_iv_remove_the_bias_of_least_squares_with_noisy_displacements():
    rng = np.random.default_rng(5)
    clean = orbit_table(TRUE, frequencies(6))
    sd = 0.1 * 5e-6  # 10 % displacement noise (orbit radius 5 um)
    sf = 0.01 * np.sqrt(np.mean(np.abs(clean.fx) ** 2 + np.abs(clean.fy) ** 2) / 2)
    trials = [with_noise(clean, rng, (sd, sd, sf, sf), stated=False) for _ in range(300)]
    z = {}
    for method, kw in (("ols", {}), ("tls", {"tls_ratio": sf / sd}), ("iv", {})):
        est, _ = _run(trials, method, **kw)
        z[method] = (est.mean(axis=0) - EXPECTED) / (est.std(axis=0, ddof=1) / np.sqrt(len(trials)))
    direct = [KEYS.index("Kxx"), KEYS.index("Kyy")]
    # least squares is attenuated: the direct stiffnesses come out too small, significantly
    assert np.all(z["ols"][direct] < -5), z["ols"].round(1)
    for method in ("tls", "iv"):
        assert np.all(np.abs(z[method]) < 3.5), (method, z[method].round(1))


def test_iv_refuses_orbits_that_are_not_one_circle():
    true = truth("kc8", {"K": (0,), "C": (0,)})
    table = orbit_table(true, frequencies(6), ((5e-6, 2e-6, 0.3), (3e-6, -4e-6, 1.1)))
    from reduction.errors import IdentificationError

    with pytest.raises(IdentificationError, match="circle"):
        identify(table, "kc8", method="iv")
