"""The two load measuring systems judged jointly (reduction.lms_comparison.lms_agreement): a chi2 of
all coefficients' differences with their covariance at a stated family-wise level, so that two
consistent systems are flagged at that rate, not at the rate of any of 12 |E_n| exceeding 2."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import stats

from support.reduction_synthetic import frequencies, orbit_table, truth
from reduction.identify import identify
from reduction.lms_comparison import LMS_LEVEL, lms_agreement, lms_difference
from reduction.statistics import joint_chi2
from reduction.systematic import Calibration, ChannelCalibration
from reduction.table import OrbitTable

TRUE = truth("kcd12", {"K": (0,), "C": (0,), "D": (0,)})
CLEAN = orbit_table(TRUE, frequencies(6))
U_F = 0.01 * float(np.sqrt(np.mean(np.abs(CLEAN.fx) ** 2)))  # 1 % force noise, stated (u_fx, u_fy)
CAL = Calibration(
    fx=ChannelCalibration(gain=0.002),
    fy=ChannelCalibration(gain=0.002),
    x=ChannelCalibration(gain=0.003),
    y=ChannelCalibration(gain=0.003),
    sensitivity=0.002,
)
DRAWS = 4000
# binomial standard deviation of a rate near 5 % over DRAWS is 0.0034; 0.015 is 4.4 of it
RATE_TOLERANCE = 0.015


def _noisy(rng: np.random.Generator, fx: np.ndarray, fy: np.ndarray) -> OrbitTable:
    e = U_F / np.sqrt(2) * rng.standard_normal((4, CLEAN.n))
    u = np.tile([0.0, 0.0, U_F, U_F], (CLEAN.n, 1))
    return OrbitTable(CLEAN.spin, CLEAN.orbit, CLEAN.x, CLEAN.y, fx + e[0] + 1j * e[1], fy + e[2] + 1j * e[3], u=u)


@pytest.fixture(scope="module")
def pair():
    """Piezo and strain fits of one point (independent force noise, shared probes), and the
    covariance of their difference (statistical + calibration)."""
    rng = np.random.default_rng(11)
    ta, tb = _noisy(rng, CLEAN.fx, CLEAN.fy), _noisy(rng, CLEAN.fx, CLEAN.fy)
    a, b = identify(ta, "kcd12"), identify(tb, "kcd12")
    _, cov = lms_difference(a, ta, b, tb, CAL, CAL)
    return a, ta, b, tb, cov


def _draws(cov: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """DRAWS differences of two consistent systems: normal with the stated covariance."""
    lam, V = np.linalg.eigh(cov)
    return (rng.standard_normal((DRAWS, lam.size)) * np.sqrt(np.clip(lam, 0, None))) @ V.T


def test_consistent_systems_are_flagged_at_the_stated_level_not_at_the_per_coefficient_rate(pair):
    a, ta, b, tb, cov = pair
    ag = lms_agreement(a, ta, b, tb, CAL, CAL)
    assert ag.level == LMS_LEVEL == 0.05 and ag.dof == 12
    assert ag.limit == pytest.approx(21.026, abs=1e-3)  # chi2(12) 95 % quantile
    diffs = _draws(cov, np.random.default_rng(5))
    chi2, dof = joint_chi2(diffs, cov)
    assert dof == 12
    assert abs(np.mean(chi2 > ag.limit) - LMS_LEVEL) < RATE_TOLERANCE
    # the old rule (any |E_n| > 2 of 12 correlated coefficients) flags far more often
    en = diffs / np.sqrt(np.diag(cov))
    assert np.mean(np.max(np.abs(en), axis=1) > 2) > 0.25


def test_a_three_sigma_offset_in_one_coefficient_is_flagged_most_of_the_time(pair):
    a, ta, b, tb, cov = pair
    limit = lms_agreement(a, ta, b, tb, CAL, CAL).limit
    i = a.free.index("Kxx")
    diffs = _draws(cov, np.random.default_rng(6))
    diffs[:, i] += 3 * np.sqrt(cov[i, i])
    chi2, _ = joint_chi2(diffs, cov)
    power = np.mean(chi2 > limit)
    # noncentral chi2(12, lambda): lambda = 9 V_ii (V^-1)_ii >= 9, the coefficients' correlation helps
    lam = 9 * cov[i, i] * np.linalg.inv(cov)[i, i]
    assert power > 0.6 and abs(power - stats.ncx2.sf(limit, 12, lam)) < 2 * RATE_TOLERANCE


def test_the_real_fits_decide_by_their_joint_chi2_and_a_gain_mismatch_is_not_consistent(pair):
    a, ta, b, tb, cov = pair
    ag = lms_agreement(a, ta, b, tb, CAL, CAL)
    assert ag.chi2 == pytest.approx(float(joint_chi2(a.theta - b.theta, cov)[0]), rel=1e-9)
    assert ag.consistent == (ag.chi2 <= ag.limit) and ag.p_value == pytest.approx(stats.chi2.sf(ag.chi2, 12))
    assert ag.max_abs == max(abs(v) for v in ag.e_n.values() if v is not None)
    strain = OrbitTable(tb.spin, tb.orbit, tb.x, tb.y, tb.fx * 1.03, tb.fy * 1.03, u=tb.u)
    off = lms_agreement(a, ta, identify(strain, "kcd12"), strain, CAL, CAL)
    assert not off.consistent and off.p_value < 1e-6
    # nothing with an uncertainty: not compared, not consistent
    bare = dataclasses.replace(a, covariance=None)
    none = lms_agreement(bare, ta, bare, ta, Calibration(), Calibration())
    assert none.chi2 is None and none.dof == 0 and not none.consistent


def test_the_joint_chi2_keeps_every_coefficient_whatever_its_unit():
    """Hand check: K in N/m has variances near 1e12, D in kg near 1e-2; the rank is judged on
    the correlations, so both count and chi2 is the plain sum of squared z-scores."""
    cov = np.diag([4e12, 9e12, 1e-2, 4e-2])
    d = np.array([2e6, -3e6, 0.1, 0.4])
    chi2, dof = joint_chi2(d, cov)
    assert dof == 4 and chi2 == pytest.approx(1.0 + 1.0 + 1.0 + 4.0, rel=1e-12)
    cov[3, 3] = 0.0  # a coefficient held fixed: left out
    assert joint_chi2(d, cov) == (pytest.approx(3.0, rel=1e-12), 3)
