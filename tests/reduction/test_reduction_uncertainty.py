"""Type-B propagation, LMS consistency, derived quantities and per-row phasor uncertainty,
against hand-checkable cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from support.reduction_synthetic import frequencies, keys_of, orbit_table, truth, with_force_noise, with_noise
from reduction.combined_dof import combined_coverage
from reduction.derived import derived_quantities
from reduction.identify import identify
from reduction.errors import ReductionError
from reduction.noise import mean_uncertainty, phasor_uncertainty, revolution_noise
from reduction.statistics import Interval, coverage_factor
from reduction.lms_comparison import lms_consistency
from reduction.systematic import Calibration, ChannelCalibration, uncertainty_budget
from reduction.table import OrbitTable

TRUE = truth("kcd12", {"K": (0,), "C": (0,), "D": (0,)})
VALUES = keys_of(TRUE)


def _fit(model="kcd12", table=None):
    table = table or orbit_table(TRUE, frequencies(10))
    return identify(table, model), table


def test_gain_error_on_the_force_channels_scales_k_c_d_by_the_gain():
    ident, table = _fit()
    g = 0.01
    budget = uncertainty_budget(ident, table, Calibration(fx=ChannelCalibration(gain=g), fy=ChannelCalibration(gain=g)))
    for key, v in VALUES.items():
        assert budget.systematic[key] == pytest.approx(g * abs(v), rel=1e-7), key
    # fx's gain only moves the coefficients of the fx equation (the x row of K, C, D)
    only_fx = uncertainty_budget(ident, table, Calibration(fx=ChannelCalibration(gain=g)))
    assert only_fx.systematic["Kxy"] == pytest.approx(g * abs(VALUES["Kxy"]), rel=1e-9)
    assert only_fx.systematic["Kyx"] < 1e-9 * abs(VALUES["Kyx"])


def test_a_force_channel_delay_shifts_d_by_minus_c_tau():
    ident, table = _fit()
    tau = 10e-6
    budget = uncertainty_budget(
        ident, table, Calibration(fx=ChannelCalibration(delay=tau), fy=ChannelCalibration(delay=tau))
    )
    j = budget.labels.index("fx.delay")
    col = dict(zip(ident.free, budget.jacobian[:, j]))
    # f e^{-i Omega tau} ~ f (1 - i Omega tau): C -> C - K tau, D -> D - C tau
    assert col["Dxx"] == pytest.approx(-VALUES["Cxx"], rel=1e-6)
    assert col["Dxy"] == pytest.approx(-VALUES["Cxy"], rel=1e-6)
    # C -> C - K tau up to the part of i Omega^3 tau D that a constant model cannot hold
    assert col["Cxx"] == pytest.approx(-VALUES["Kxx"], rel=1e-2)
    assert budget.systematic["Dxx"] == pytest.approx(abs(VALUES["Cxx"]) * tau, rel=1e-6)
    # the example: a 10 us delay moves Dxx by -C tau = -0.4 kg here (C = 4e4 N s/m)
    assert budget.systematic["Dxx"] == pytest.approx(0.4, rel=1e-6)


def test_budget_keeps_statistical_systematic_and_combined_apart():
    rng = np.random.default_rng(3)
    clean = orbit_table(TRUE, frequencies(10))
    s = 1e-3 * np.sqrt(np.mean(np.abs(clean.fx) ** 2))
    noisy = OrbitTable(
        clean.spin,
        clean.orbit,
        clean.x,
        clean.y,
        clean.fx + s * rng.standard_normal(clean.n),
        clean.fy + s * rng.standard_normal(clean.n),
    )
    ident = identify(noisy, "kcd12")
    cal = Calibration(
        fx=ChannelCalibration(gain=0.005, phase=np.radians(0.1)),
        fy=ChannelCalibration(gain=0.005),
        x=ChannelCalibration(gain=0.002),
        sensitivity=0.01,
    )
    b = uncertainty_budget(ident, noisy, cal)
    cov = combined_coverage(ident, b, cal, math.inf)  # U and its k: their one owner
    for key in ident.coefficients:
        assert b.combined[key] == pytest.approx(np.hypot(b.statistical[key], b.systematic[key]), rel=1e-9)
        # the calibration stated exactly: Welch-Satterthwaite over the fit's dof alone
        nu = ident.dof * (b.combined[key] / b.statistical[key]) ** 4
        assert cov.dof[key] == pytest.approx(nu, rel=1e-9)
        assert cov.k[key] == pytest.approx(coverage_factor(Interval.STUDENT_T, nu), rel=1e-9) and cov.k[key] > 2
        assert cov.expanded[key] == pytest.approx(cov.k[key] * b.combined[key], rel=1e-12)
    # a relative probe sensitivity error on x scales the x column of Z: Kxx by -1 %
    j = b.labels.index("x.sensitivity")
    assert dict(zip(ident.free, b.jacobian[:, j]))["Kxx"] == pytest.approx(-ident.coefficients["Kxx"], rel=1e-3)


def _noisy_with_unequal_u(seed: int = 5) -> OrbitTable:
    """kcd12's table with force noise and stated u_fx, u_fy 1 to 100 times apart from row to row
    (u_x = u_y = 0: the wls weights do not move with the coefficients)."""
    rng = np.random.default_rng(seed)
    clean = orbit_table(TRUE, frequencies(10))
    s = 1e-3 * np.sqrt(np.mean(np.abs(clean.fx) ** 2)) * np.geomspace(1, 100, clean.n)
    u = np.stack([np.zeros(clean.n), np.zeros(clean.n), s, s], axis=1)
    fx = clean.fx + s * (rng.standard_normal(clean.n) + 1j * rng.standard_normal(clean.n)) / np.sqrt(2)
    fy = clean.fy + s * (rng.standard_normal(clean.n) + 1j * rng.standard_normal(clean.n)) / np.sqrt(2)
    return OrbitTable(clean.spin, clean.orbit, clean.x, clean.y, fx, fy, u=u)


@pytest.mark.parametrize("method", ["ols", "wls"])
def test_a_calibration_term_goes_through_the_map_the_fit_used(method):
    """An ols fit weighs its equations equally whatever its u_* columns say: the force gains'
    systematic term is the change of the coefficients when the forces are off by their stated
    gain error and the table is fitted again by the same method (the forces enter linearly: exact
    to rounding), for ols and wls alike. With u_* 1 to 100 times apart the u-weighted map gave
    ols another term."""
    table = _noisy_with_unequal_u()
    ident = identify(table, "kcd12", method=method)
    g = {"fx": 0.1, "fy": 0.04}  # large: exact either way, the refit's rounding smaller
    b = uncertainty_budget(
        ident, table, Calibration(fx=ChannelCalibration(gain=g["fx"]), fy=ChannelCalibration(gain=g["fy"]))
    )
    moved = []
    for c, gain in g.items():
        t = OrbitTable(
            table.spin,
            table.orbit,
            table.x,
            table.y,
            table.fx * (1 + gain * (c == "fx")),
            table.fy * (1 + gain * (c == "fy")),
            u=table.u,
        )
        moved.append(np.array(identify(t, "kcd12", method=method).theta) - np.array(ident.theta))
    refit = np.sqrt(np.sum(np.square(moved), axis=0))
    for key, v in ident.spec.expand(refit).items():
        assert b.systematic[key] == pytest.approx(v, rel=1e-9), key


def test_load_systems_agree_within_uncertainty_and_a_gain_mismatch_shows():
    piezo = orbit_table(TRUE, frequencies(10))
    strain = OrbitTable(piezo.spin, piezo.orbit, piezo.x, piezo.y, piezo.fx * 1.03, piezo.fy * 1.03)
    a, b = identify(piezo, "kcd12"), identify(strain, "kcd12")
    cal = Calibration(
        fx=ChannelCalibration(gain=0.005),
        fy=ChannelCalibration(gain=0.005),
        x=ChannelCalibration(gain=0.01),
        y=ChannelCalibration(gain=0.01),
    )
    en = lms_consistency(a, piezo, b, strain, cal, cal)
    # Kxx: difference -3 % of Kxx; u(diff)^2 = (0.5 % of each system's Kxx)^2 plus the shared x-probe
    # gain (1 %), which moves both Kxx alike and leaves only 1 % of their 3 % difference
    u = np.sqrt(0.005**2 * (1 + 1.03**2) + (0.01 * 0.03) ** 2)
    assert en["Kxx"] == pytest.approx(-0.03 / u, rel=1e-6)
    same = lms_consistency(a, piezo, a, piezo, cal, cal)
    assert all(abs(v) < 1e-6 for v in same.values() if v is not None)


def test_derived_quantities_match_hand_formulas():
    true = truth("kc8", {"K": (0,), "C": (0,)})
    table = orbit_table(true, frequencies(10))
    ident = identify(table, "kc8")
    K, C = true[("K", 0)], true[("C", 0)]
    w = np.linspace(20.0, 2000.0, 200)
    d = derived_quantities(ident, w, table.spin)
    assert np.allclose(d.c_eff_xx, C[0, 0] - K[0, 1] / w, rtol=1e-9)
    assert np.allclose(d.c_eff_yy, C[1, 1] + K[1, 0] / w, rtol=1e-9)
    assert d.c_eff_zero_xx[0] == pytest.approx(K[0, 1] / C[0, 0], rel=1e-9)
    assert d.c_eff_zero_yy[0] == pytest.approx(-K[1, 0] / C[1, 1], rel=1e-9)
    Z = K[None] + 1j * w[:, None, None] * C[None]
    hf = (Z[:, 0, 0] + Z[:, 1, 1]) / 2 + 1j * (Z[:, 1, 0] - Z[:, 0, 1]) / 2
    hb = (Z[:, 0, 0] + Z[:, 1, 1]) / 2 + 1j * (Z[:, 0, 1] - Z[:, 1, 0]) / 2
    assert np.allclose(d.h_forward, hf, rtol=1e-9) and np.allclose(d.h_backward, hb, rtol=1e-9)
    assert np.allclose(d.wfr, (K[0, 1] - K[1, 0]) / (table.spin * (C[0, 0] + C[1, 1])), rtol=1e-9)


def test_effective_damping_with_inertia_is_what_its_docstring_says():
    """kcd11 (D symmetric, D_xy != 0): C_eff leaves D out, so the damping a forward circle
    feels in x, -Im(f_x) / (Omega R) of the paper's Eq. 7, is C_eff,xx + Omega D_xy (in y,
    Re(f_y) / (-Omega R) is C_eff,yy - Omega D_yx); the mean of the two is Im H_f / Omega."""
    true = truth("kcd11", {"K": (0,), "C": (0,), "D": (0,)})
    table = orbit_table(true, frequencies(10))
    ident = identify(table, "kcd11")
    D = true[("D", 0)]
    assert D[0, 1] == D[1, 0] != 0
    w = np.linspace(20.0, 400.0, 50)
    d = derived_quantities(ident, w, table.spin)
    Z = ident.impedance(w)
    R = 1e-5
    fx = -(Z[:, 0, 0] * R + Z[:, 0, 1] * (-1j * R))
    fy = -(Z[:, 1, 0] * R + Z[:, 1, 1] * (-1j * R))
    np.testing.assert_allclose(-fx.imag / (w * R), d.c_eff_xx + w * D[0, 1], rtol=1e-9)
    np.testing.assert_allclose(-fy.real / (w * R), d.c_eff_yy - w * D[1, 0], rtol=1e-9)
    np.testing.assert_allclose((d.c_eff_xx + d.c_eff_yy) / 2, d.h_forward.imag / w, rtol=1e-9)


def test_derived_uncertainty_is_the_covariance_propagation():
    true = truth("kc8", {"K": (0,), "C": (0,)})
    table = orbit_table(true, frequencies(10))
    ident = identify(table, "kc8")
    cov = np.diag(np.arange(1.0, 9.0)) * 1e6  # Kxx .. Cyy variances (free order is the key order)
    w = np.array([100.0, 400.0])
    d = derived_quantities(ident, w, table.spin, cov)
    i = {k: j for j, k in enumerate(ident.free)}
    expect = np.sqrt(cov[i["Cxx"], i["Cxx"]] + cov[i["Kxy"], i["Kxy"]] / w**2)
    assert np.allclose(d.c_eff_xx_std, expect, rtol=1e-12)
    # Re H_f = (Kxx + Kyy)/2 - Omega (Cyx - Cxy)/2
    re_f = np.sqrt(
        (cov[i["Kxx"], i["Kxx"]] + cov[i["Kyy"], i["Kyy"]] + w**2 * (cov[i["Cxy"], i["Cxy"]] + cov[i["Cyx"], i["Cyx"]]))
        / 4
    )
    assert np.allclose(d.h_forward_std[0], re_f, rtol=1e-12)


def test_phasor_uncertainty_is_scatter_over_root_n():
    q = np.array([1 + 1j, 1 - 1j, 3 + 1j, 3 - 1j])  # mean 2, |q - mean|^2 = 2 each
    assert phasor_uncertainty(q) == pytest.approx(np.sqrt(8 / 3) / 2)
    rng = np.random.default_rng(0)
    rec = 5 + 0.1 / np.sqrt(2) * (rng.standard_normal((400, 50)) + 1j * rng.standard_normal((400, 50)))
    u = phasor_uncertainty(rec, axis=1)  # 400 rows of 50 records, E|noise|^2 = 0.01
    assert np.mean(u) == pytest.approx(0.1 / np.sqrt(50), rel=0.02)
    # it is the actual error of the averages: E|mean - 5|^2 = u^2
    assert np.sqrt(np.mean(np.abs(rec.mean(axis=1) - 5) ** 2)) == pytest.approx(0.1 / np.sqrt(50), rel=0.1)
    assert np.isinf(phasor_uncertainty(np.array([1 + 0j])))


@pytest.mark.parametrize("spin_turns", [np.nan, np.inf, -2.5])
def test_a_spin_ratio_that_is_no_ratio_is_refused(spin_turns):
    """omega/|Omega| NaN or inf fitted no spin tone at all (every comparison with it false) and
    returned the plain scatter as if the ratio were known; negative is no ratio either."""
    q = 1 + 0.1 * np.exp(2j * np.pi * 2.5 * np.arange(20))[:, None]
    assert np.isfinite(mean_uncertainty(q, 2.5)).all()
    for f in (mean_uncertainty, revolution_noise):
        with pytest.raises(ReductionError, match="spin_turns"):
            f(q, spin_turns)


def test_a_non_finite_revolution_phasor_is_refused():
    q = np.ones((20, 2), dtype=complex)
    q[4, 1] = np.nan
    for f in (phasor_uncertainty, lambda r: mean_uncertainty(r, 2.5), lambda r: revolution_noise(r, 2.5)):
        with pytest.raises(ReductionError, match="not finite"):
            f(q)


def _calibration_error(rng, ch: ChannelCalibration, orbit, sensitivity: float = 0.0):
    """One draw of a channel's calibration error factor (1 + g + s) exp(-i (phi + Omega tau)),
    s the probes' common sensitivity error as drawn (0 for a force channel)."""
    gain = 1 + rng.normal(0, ch.gain) + sensitivity
    return gain * np.exp(-1j * (rng.normal(0, ch.phase) + orbit * rng.normal(0, ch.delay)))


@pytest.mark.slow
def test_linearised_systematic_propagation_matches_a_monte_carlo_of_calibration_errors():
    ident, table = _fit()
    cal = Calibration(
        x=ChannelCalibration(gain=0.005, phase=np.radians(0.1), delay=2e-6),
        y=ChannelCalibration(gain=0.005, phase=np.radians(0.1), delay=2e-6),
        fx=ChannelCalibration(gain=0.01, phase=np.radians(0.3), delay=10e-6),
        fy=ChannelCalibration(gain=0.01, phase=np.radians(0.3), delay=10e-6),
        sensitivity=0.01,
    )
    budget = uncertainty_budget(ident, table, cal)
    rng = np.random.default_rng(8)
    draws = []
    w = table.orbit
    for _ in range(400):
        s = rng.normal(0, cal.sensitivity)  # one error for every probe
        t = OrbitTable(
            table.spin,
            w,
            table.x * _calibration_error(rng, cal.x, w, s),
            table.y * _calibration_error(rng, cal.y, w, s),
            table.fx * _calibration_error(rng, cal.fx, w),
            table.fy * _calibration_error(rng, cal.fy, w),
        )
        coefficients = identify(t, "kcd12").coefficients  # one identification per draw
        draws.append([coefficients[k] for k in VALUES])
    spread = np.std(draws, axis=0, ddof=1)
    linear = np.array([budget.systematic[k] for k in VALUES])
    # 400 draws: the sample std is good to 3.5 % (1 sigma); the first-order model to ~1 %. A false
    # failure needs a 4 sigma excursion on one of 12 coefficients: P < 12 x 6.3e-5 = 8e-4
    np.testing.assert_allclose(spread, linear, rtol=0.15)


@pytest.mark.parametrize("model", ["kcd11", "kc7"])
def test_the_probes_sensitivity_is_one_error_for_x_and_y(model):
    """A sensitivity error s common to every probe scales every displacement by 1 + s, so every
    coefficient by 1 / (1 + s): u = s |value| for each, the symmetric entry (kcd11's Dxy = Dyx,
    kc7's Cxy = Cyx) too, which x and y taken as independent errors gave s |value| / sqrt(2)."""
    true = truth(model, {"K": (0,), "C": (0,), "D": (0,)} if model == "kcd11" else {"K": (0,), "C": (0,)})
    table = orbit_table(true, frequencies(10))
    ident = identify(table, model)
    b = uncertainty_budget(ident, table, Calibration(sensitivity=0.01))
    for key, v in ident.coefficients.items():
        assert b.systematic[key] == pytest.approx(0.01 * abs(v), rel=1e-6), key


def test_a_displacement_error_moves_an_ols_fit_through_its_residual_too():
    """A displacement error changes the regression matrix: beside P (Z dd) the estimate moves by
    (A^T A)^-1 dA^T r, r the fit's residual (reduction.systematic.map_change). Monte Carlo on a
    table with 1 % force noise: 300 draws of a delay on x (2 µs) and a phase error on y (0.1 deg),
    refitted by ols; each coefficient's spread is its systematic u within 15 % (300 draws: the
    sample std to 4 %, 1 sigma; 0.92 to 1.05 here). Without the residual's part Kxx and Kyx had
    none of their spread (14 and 2.4 N/m) and Kxy twice its own: for these errors the residual's
    part is most of the change."""
    rng = np.random.default_rng(11)
    clean = orbit_table(TRUE, frequencies(10))
    table = with_force_noise(clean, rng, 1e-2 * np.sqrt(np.mean(np.abs(clean.fx) ** 2)))
    ident = identify(table, "kcd12")
    cal = Calibration(x=ChannelCalibration(delay=2e-6), y=ChannelCalibration(phase=np.radians(0.1)))
    budget = uncertainty_budget(ident, table, cal)
    draws = []
    for _ in range(300):
        x = table.x * np.exp(-1j * table.orbit * rng.normal(0, cal.x.delay))
        y = table.y * np.exp(-1j * rng.normal(0, cal.y.phase))
        fit = identify(OrbitTable(table.spin, table.orbit, x, y, table.fx, table.fy), "kcd12")
        draws.append([fit.coefficients[k] for k in VALUES])
    spread = np.std(draws, axis=0, ddof=1)
    np.testing.assert_allclose([budget.systematic[k] for k in VALUES], spread, rtol=0.15)


def test_a_displacement_error_moves_a_wls_fit_on_u_through_its_residual_too():
    """wls on u_* counts the residual's part with its own weights, as wls on coherences: force noise
    0.3 to 3 % from row to row and 1 % on the displacements, stated as u_*; 300 draws of the errors
    of the ols test above, refitted by wls. Each coefficient's spread is its systematic u within
    15 % (0.92 to 1.06 here); without the residual's part 0.71 to 1.49. The weights' own motion with
    the coefficients (the effective variances at the fit) is left out: within those figures."""
    rng = np.random.default_rng(11)
    clean = orbit_table(TRUE, frequencies(10))
    sf = 1e-2 * np.sqrt(np.mean(np.abs(clean.fx) ** 2)) * np.geomspace(0.3, 3, clean.n)
    sd = 1e-2 * np.sqrt(np.mean(np.abs(clean.x) ** 2))
    table = with_noise(clean, rng, (sd, sd, sf, sf))
    cal = Calibration(x=ChannelCalibration(delay=2e-6), y=ChannelCalibration(phase=np.radians(0.1)))
    budget = uncertainty_budget(identify(table, "kcd12", method="wls"), table, cal)
    draws = []
    for _ in range(300):
        x = table.x * np.exp(-1j * table.orbit * rng.normal(0, cal.x.delay))
        y = table.y * np.exp(-1j * rng.normal(0, cal.y.phase))
        fit = identify(OrbitTable(table.spin, table.orbit, x, y, table.fx, table.fy, u=table.u), "kcd12", method="wls")
        draws.append([fit.coefficients[k] for k in VALUES])
    spread = np.std(draws, axis=0, ddof=1)
    np.testing.assert_allclose([budget.systematic[k] for k in VALUES], spread, rtol=0.15)
