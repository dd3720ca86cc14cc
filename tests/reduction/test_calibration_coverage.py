"""Coverage of the calibration fits' expanded uncertainty U = k u (reduction.calibration.expanded).

Monte Carlo on simulated fits: the gain matrix from the default 7 loads (2 (7 - 3) = 8 degrees of
freedom) and a probe's line from 5 steps (3), each drawn N times with fresh reading noise. Each fit
is judged at every entry; the share within U is compared with its target at a tolerance of 3
binomial standard deviations of N independent fits (the entries of one fit share its residual
variance, so N fits, not N x entries, bound the spread): k = 2 covers 91.9 % at 8 dof and 86.1 % at
3, Student's t (2.37, 3.31) the 95.45 % of U_COVERAGE.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from reduction.calibration import expanded, fit_gain_matrix, fit_probe, static_loads
from reduction.statistics import U_COVERAGE, Interval, coverage_factor, coverage_probability, effective_dof

G = np.array([[1.02, 0.03], [-0.02, 0.97]])  # the true gain matrix, cross terms of a few percent
OFFSET = np.array([3.0, -2.0])  # N


def _tolerance(p: float, n: int) -> float:
    """3 binomial standard deviations of a share p over n independent fits."""
    return 3 * math.sqrt(p * (1 - p) / n)


def _gain_fits(n: int, noise_n: float, reference_u: float, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(|error| / u, k, u) of every entry of n gain-matrix fits, each (n, 2, 2): readings with
    noise_n N of noise, the reference's loads off by one common relative error of u reference_u."""
    rng = np.random.default_rng(seed)
    loads = static_loads(500.0)
    z, ks, us = [], [], []
    for _ in range(n):
        applied = loads * (1 + reference_u * rng.standard_normal())  # the reference's own error
        reading = np.linalg.solve(G, (applied - OFFSET).T).T + rng.normal(0.0, noise_n, loads.shape)
        fit = fit_gain_matrix(loads, reading, reference_u)
        k, _ = expanded(fit.gain_u, fit.gain_u_fit, fit.dof)
        z.append(np.abs(fit.gain - G) / fit.gain_u)
        ks.append(k)
        us.append(fit.gain_u)
    return np.array(z), np.array(ks), np.array(us)


def test_the_coverage_factor_is_students_t_at_the_fits_degrees_of_freedom():
    assert coverage_factor(Interval.STUDENT_T, 8) == pytest.approx(2.366, rel=1e-3)
    assert coverage_factor(Interval.STUDENT_T, 3) == pytest.approx(3.307, rel=1e-3)
    assert coverage_factor(Interval.STUDENT_T, math.inf) == pytest.approx(2.0, rel=1e-5)
    assert coverage_probability(2.0, 8) == pytest.approx(0.9195, rel=1e-3)
    # Welch-Satterthwaite: a reference part known exactly adds no dof's doubt
    nu = effective_dof(np.array([1.0, 2.0, 1.0]), np.array([1.0, 1.0, 0.0]), 8)
    assert nu[0] == 8 and nu[1] == 8 * 16 and math.isinf(nu[2])


def test_the_gain_matrix_u_at_8_dof_covers_95_percent_with_students_k_and_92_with_k_2():
    n = 3000
    z, k, _ = _gain_fits(n, noise_n=2.0, reference_u=0.0, seed=1)
    assert np.allclose(k, coverage_factor(Interval.STUDENT_T, 8))  # the reference exact: the fit's dof
    new, old = float(np.mean(z <= k)), float(np.mean(z <= 2.0))
    assert abs(new - U_COVERAGE) <= _tolerance(U_COVERAGE, n), new
    p2 = coverage_probability(2.0, 8)
    assert abs(old - p2) <= _tolerance(p2, n), old  # 91.9 %: k = 2 under-covers
    assert new - old > 0.02


def test_a_reference_part_raises_the_effective_dof_and_the_coverage_stays_95_percent():
    n = 3000
    # 0.6 % of reference: it dominates the diagonal entries' u (effective dof in the hundreds, k
    # about 2), the cross terms' (0.6 % of 0.03) stay the fit's (k about 2.37)
    z, k, _ = _gain_fits(n, noise_n=2.0, reference_u=0.006, seed=2)
    assert np.median(k[:, 0, 0]) < 2.05 and np.median(k[:, 0, 1]) > 2.3
    share = float(np.mean(z <= k))
    assert abs(share - U_COVERAGE) <= _tolerance(U_COVERAGE, n) + 0.01, share  # Welch-Satterthwaite: approximate


def test_a_probes_line_of_5_steps_covers_95_percent_with_students_k_and_86_with_k_2():
    n = 3000
    rng = np.random.default_rng(3)
    steps = np.linspace(-20e-6, 20e-6, 5)
    gain = 1.013
    z, ks = [], []
    for _ in range(n):
        fit = fit_probe(steps, steps / gain + rng.normal(0.0, 20e-9, steps.size), 0.0)
        k, _ = expanded(np.array(fit.gain_u), np.array(fit.gain_u_fit), fit.dof)
        z.append(abs(fit.gain - gain) / fit.gain_u)
        ks.append(float(k))
    assert fit.dof == 3 and np.allclose(ks, coverage_factor(Interval.STUDENT_T, 3))
    new, old = float(np.mean(np.array(z) <= np.array(ks))), float(np.mean(np.array(z) <= 2.0))
    assert abs(new - U_COVERAGE) <= _tolerance(U_COVERAGE, n), new
    p2 = coverage_probability(2.0, 3)
    assert abs(old - p2) <= _tolerance(p2, n), old  # 86.1 %
