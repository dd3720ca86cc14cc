"""Coverage of the combined expanded uncertainty U = k u_c of the identified coefficients
(reduction.combined_dof): k Student's t at the Welch-Satterthwaite effective dof of the
statistical part and the calibration parts, each with its own dof.

Hand checks of the effective dof, then a Monte Carlo: one fit of a table with u_* columns (its
statistical covariance known: normal, infinite dof) whose force channels' gain error is drawn
from the calibration's true u, while the u the record states is that u's estimate from a
gain-matrix fit of 3 dof (true u x sqrt(chi2_3 / 3), one draw for both channels: one fit's
residual); the coefficients' errors are the fit's own (drawn from its covariance) plus the gain
errors through the budget's Jacobian (the budget's linearisation, exact for a gain error on
both force channels, which scales K, C, D). Tolerances: 3 binomial standard deviations of N
independent trials (each trial's coefficients share its draws, so N, not N x coefficients).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from support.reduction_synthetic import frequencies, orbit_table, truth, with_noise
from reduction.combined_dof import calibration_parts, combined_coverage
from reduction.identify import identify
from reduction.statistics import U_COVERAGE, Interval, coverage_factor, welch_satterthwaite
from reduction.systematic import Calibration, ChannelCalibration, uncertainty_budget

TRUE = truth("kc8", {"K": (0,), "C": (0,)})


def _fit(seed: int = 1, stated: bool = True):
    clean = orbit_table(TRUE, frequencies(4))
    s = 3e-3 * float(np.sqrt(np.mean(np.abs(clean.fx) ** 2)))
    table = with_noise(clean, np.random.default_rng(seed), (0, 0, s, s), stated=stated)
    return identify(table, "kc8"), table


def _gains(u: float, dof: float) -> Calibration:
    return Calibration(fx=ChannelCalibration(gain=u, gain_dof=dof), fy=ChannelCalibration(gain=u, gain_dof=dof))


def test_welch_satterthwaite_by_hand():
    one = np.array([1.0])
    # one part dominant: about its own dof
    assert welch_satterthwaite(one, [one, 1e-3 * one], [3, 5])[0] == pytest.approx(3, rel=1e-6)
    # two equal independent parts of dof 4 each: (2 u^2)^2 / (2 u^4 / 4) = 8
    half = np.sqrt(0.5) * one
    assert welch_satterthwaite(one, [half, half], [4, 4])[0] == pytest.approx(8)
    # an exact part (a certificate) of equal size beside one of dof 4: 4 (u / u_part)^4 = 16
    assert welch_satterthwaite(one, [half, half], [math.inf, 4])[0] == pytest.approx(16)
    assert math.isinf(welch_satterthwaite(one, [one], [math.inf])[0])


def test_a_part_of_0_adds_nothing_whatever_its_dof():
    one, zero = np.array([1.0]), np.array([0.0])
    # the statistical part of a fit without covariance (dof 0) beside a calibration part of 5 dof
    assert welch_satterthwaite(one, [one, zero], [5, 0])[0] == pytest.approx(5)  # was inf: 0 / 0 in the sum
    assert math.isinf(welch_satterthwaite(zero, [zero, zero], [3, 0])[0])
    assert welch_satterthwaite(one, [one], [0])[0] == 0  # a part not 0 at dof 0: no dof at all


def test_the_parts_group_what_one_fit_estimated():
    cal = Calibration(
        fx=ChannelCalibration(gain_dof=8, lag_dof=3),
        fy=ChannelCalibration(gain_dof=8, lag_dof=4),
        x=ChannelCalibration(gain_dof=3),
    )
    parts = dict((tuple(names), dof) for names, dof in calibration_parts(cal))
    assert parts[("fx.gain", "fy.gain")] == 8  # one gain-matrix fit
    assert parts[("fx.phase", "fx.delay")] == 3 and parts[("fy.phase", "fy.delay")] == 4  # each a line
    assert parts[("x.gain",)] == 3 and math.isinf(parts[("y.gain",)])
    assert math.isinf(parts[("x.sensitivity", "y.sensitivity")])
    labels, _ = cal.parameters()
    assert sorted(n for names in parts for n in names) == sorted(labels)


def test_a_dominant_calibration_part_gives_its_own_dof_and_exact_parts_k_2():
    ident, table = _fit()
    assert ident.interval == Interval.NORMAL
    big = 0.05  # 5 % gain: the fit's own u is far below it on every K, C
    c = combined_coverage(ident, uncertainty_budget(ident, table, _gains(big, 3)), _gains(big, 3), math.inf)
    assert c.dof["Kxx"] == pytest.approx(3, rel=0.02) and c.k["Kxx"] == pytest.approx(3.31, abs=0.05)
    exact = combined_coverage(ident, uncertainty_budget(ident, table, _gains(big, math.inf)), _gains(big, 3), 3)
    assert exact.k["Kxx"] == pytest.approx(3.31, abs=0.05)  # the dof of the Calibration given, not the budget's
    exact = combined_coverage(ident, uncertainty_budget(ident, table, _gains(big, 3)), _gains(big, math.inf), 3)
    assert all(math.isinf(v) for v in exact.dof.values()) and all(
        k == pytest.approx(2.0, abs=1e-5) for k in exact.k.values()
    )
    b = uncertainty_budget(ident, table, _gains(big, 3))
    assert c.expanded["Kxx"] == pytest.approx(c.k["Kxx"] * b.combined["Kxx"])


def test_without_calibration_dof_a_residual_fit_keeps_its_own_students_k():
    ident, table = _fit(stated=False)
    assert ident.interval == Interval.STUDENT_T
    c = combined_coverage(ident, uncertainty_budget(ident, table, Calibration()), Calibration(), math.inf)
    assert set(c.dof.values()) == {ident.dof}
    assert c.k["Kxx"] == pytest.approx(coverage_factor(Interval.STUDENT_T, ident.dof))


def test_combined_u_with_calibration_of_3_dof_covers_95_percent_with_k_of_nu_eff_and_less_with_k_2():
    ident, table = _fit()
    rng = np.random.default_rng(11)
    n, u_true, dof = 600, 4e-3, 3
    free, unit = list(ident.free), uncertainty_budget(ident, table, _gains(1.0, dof))
    J = unit.jacobian[:, [unit.labels.index(name) for name in ("fx.gain", "fy.gain")]]
    root = np.linalg.cholesky((ident.covariance + ident.covariance.T) / 2)
    hit_new, hit_2, nus = [], [], []
    for _ in range(n):
        err = root @ rng.standard_normal(len(free)) + J @ (u_true * rng.standard_normal(2))
        stated = u_true * math.sqrt(rng.chisquare(dof) / dof)
        cal = _gains(stated, dof)
        budget = uncertainty_budget(ident, table, cal)
        c = combined_coverage(ident, budget, cal, math.inf)
        u_c = np.array([budget.combined[k] for k in free])
        k = np.array([c.k[key] for key in free])
        hit_new.append(np.abs(err) <= k * u_c)
        hit_2.append(np.abs(err) <= 2 * u_c)
        nus.append([c.dof[key] for key in free])
    new, old = np.mean(hit_new, axis=0), np.mean(hit_2, axis=0)
    tol = 3 * math.sqrt(U_COVERAGE * (1 - U_COVERAGE) / n)
    calibrated = [i for i, key in enumerate(free) if np.median(np.array(nus)[:, i]) < 30]  # the gain's share large
    assert len(calibrated) >= 4, np.median(nus, axis=0)
    for i in calibrated:
        assert abs(new[i] - U_COVERAGE) <= tol + 0.01, (free[i], new[i])  # Welch-Satterthwaite: approximate
        assert old[i] < U_COVERAGE - tol, (free[i], old[i])  # k = 2 covers clearly less
    assert float(np.mean(new[calibrated])) == pytest.approx(U_COVERAGE, abs=tol)
    assert float(np.mean(U_COVERAGE - old[calibrated])) > 0.03  # seed 11: K 94.0 % against 88.6 % with k = 2
