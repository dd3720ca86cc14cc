"""reduction.allocation (revolutions per ratio in the least rig time) and the spin-tone-aware
phasor noise of reduction.noise, against hand-checkable limits and Monte Carlo spreads."""

from __future__ import annotations

import math

import numpy as np
import pytest

from orbitrig.cli.design_inputs import NOMINAL
from reduction.allocation import allocate, revolution_information, revolution_time, time_shares
from reduction.design import design_orbits
from reduction.errors import ReductionError
from reduction.frequency_list import DesignProblem, allowed_ratios, predict
from reduction.identify import identify
from reduction.impedance import forces, impedance
from reduction.models import model_spec
from reduction.noise import mean_uncertainty, phasor_uncertainty, revolution_noise
from reduction.table import OrbitTable

SPIN = 1000 * 2 * math.pi / 60
PAPER = [round(0.2 + k / 9, 6) for k in range(10)]
U = np.array([20e-9, 20e-9, 15.0, 15.0])  # per revolution: x, y (m), fx, fy (N)
RADIUS = 2.4e-6


def theta(spec):
    return np.array([NOMINAL.get(n, 0.0) for n in spec.names])


def paper_errors(spec) -> np.ndarray:
    p = DesignProblem(spec, theta(spec), SPIN, RADIUS, U, 50)
    return predict(p, PAPER).std_errors


# ------------------------------------------------------------------ noise with spin tones
def tone_blocks(rng, trials, n, spin_turns, sigma=1.0, tone=3.0):
    """(trials, n) per-revolution phasors: mean 0, white noise sigma, a spin tone of size
    ``tone`` at random phase leaking as tone e^{i 2 pi spin_turns k}."""
    k = np.arange(n)
    phase = np.exp(2j * np.pi * rng.random((trials, 1)))
    white = sigma * (rng.standard_normal((trials, n)) + 1j * rng.standard_normal((trials, n))) / math.sqrt(2)
    return tone * phase * np.exp(2j * np.pi * spin_turns * k) + white


def test_revolution_noise_takes_the_rotating_tone_out_of_the_scatter():
    rng = np.random.default_rng(1)
    q = tone_blocks(rng, 400, 60, 1 / 0.7)
    white = np.array([revolution_noise(b[:, None], 1 / 0.7)[0] for b in q])
    scatter = np.array([phasor_uncertainty(b[:, None])[0] * math.sqrt(60) for b in q])
    # E sigma_hat^2 = 1 (unbiased with n - 5 degrees of freedom); 400 blocks: +-3 % (1 sigma)
    assert np.mean(white**2) == pytest.approx(1.0, abs=0.1)
    assert np.mean(scatter**2) > 8  # 1 + 3^2: the scatter counts the tone as noise


def test_mean_uncertainty_matches_the_spread_of_the_mean():
    """Over 2000 blocks of 50 revolutions: RMS(mean error) / RMS(u) within 1 +- 0.06
    (2000 samples of a chi-square-like spread: 1 sigma about 2 %); the plain scatter would
    claim 2.5 times the error here."""
    rng = np.random.default_rng(2)
    for ratio in (0.7, 0.9, 1.2):
        q = tone_blocks(rng, 2000, 50, 1 / ratio)
        err = np.abs(q.mean(axis=1))
        u = np.array([mean_uncertainty(b[:, None], 1 / ratio)[0] for b in q])
        assert np.sqrt(np.mean(err**2)) / np.sqrt(np.mean(u**2)) == pytest.approx(1.0, abs=0.06), ratio
        scatter = np.array([phasor_uncertainty(b[:, None])[0] for b in q])
        assert np.sqrt(np.mean(scatter**2)) > 1.5 * np.sqrt(np.mean(err**2))


def test_coinciding_and_unresolvable_tones_stay_finite():
    rng = np.random.default_rng(3)
    # ratio 0.6: -1 x spin and +2 x spin advance alike (1/3 turn): one column, not two
    q = tone_blocks(rng, 1, 40, 1 / 0.6)[0][:, None]
    assert np.all(np.isfinite(revolution_noise(q, 1 / 0.6)))
    # ratio 0.5: the tones are orbit harmonics (no leakage); one revolution: inf, as the scatter
    q = tone_blocks(rng, 1, 40, 2.0, tone=0.0)[0][:, None]
    assert mean_uncertainty(q, 2.0) == pytest.approx(phasor_uncertainty(q), rel=0.05)
    assert np.isinf(mean_uncertainty(q[:1], 2.0)).all()
    # three revolutions at ratio 0.7 resolve one tone (+1 x spin); the others are too close
    assert np.isfinite(revolution_noise(q[:3], 1 / 0.7)).all()


def test_dropped_revolutions_keep_the_tone_in_step():
    """Revolutions 20..29 dropped (damaged frames): the tone still turns through them, so the
    fit must use the board's revolution numbers; counted as consecutive records it would
    leave the tone in the residual scatter."""
    rng = np.random.default_rng(5)
    revs = np.r_[np.arange(20), np.arange(30, 80)]
    q = 3.0 * np.exp(2j * np.pi * (1 / 0.7) * revs) + (
        rng.standard_normal(70) + 1j * rng.standard_normal(70)
    ) / math.sqrt(2)
    right = revolution_noise(q[:, None], 1 / 0.7, revolutions=revs)[0]
    wrong = revolution_noise(q[:, None], 1 / 0.7)[0]
    assert right == pytest.approx(1.0, abs=0.25) and wrong > 1.5
    with pytest.raises(ReductionError):
        revolution_noise(q[:, None], 1 / 0.7, revolutions=revs[:-1])


# ------------------------------------------------------------------ allocation
def test_information_adds_up_to_the_cramer_rao_bound():
    spec = model_spec("kcd11")
    F = revolution_information(spec, theta(spec), SPIN, RADIUS, PAPER, U)
    cov = np.linalg.inv(50 * F.sum(axis=0))
    assert np.sqrt(np.diag(cov)) == pytest.approx(paper_errors(spec), rel=1e-6)
    assert revolution_time([0.5], SPIN) == pytest.approx(2 * 2 * math.pi / (0.5 * SPIN))


def test_kc8_goes_to_the_top_ratio():
    """K (information per second ~ r) and C (~ r^3) are both cheapest at the highest ratio,
    and one frequency in both directions identifies the 8 coefficients."""
    spec = model_spec("kc8")
    a = allocate(spec, theta(spec), SPIN, RADIUS, allowed_ratios(0.2, 1.5), U, paper_errors(spec), block_overhead=2.05)
    assert a.ratios == (1.5,)
    assert a.worst <= 1.0
    assert a.revolutions[0] >= 10


def test_allocation_reaches_the_target_cheaper_than_any_even_split():
    spec = model_spec("kcd11")
    scales = paper_errors(spec)
    a = allocate(spec, theta(spec), SPIN, RADIUS, allowed_ratios(0.2, 1.5), U, scales, block_overhead=2.05)
    F = revolution_information(spec, theta(spec), SPIN, RADIUS, a.ratios, U)
    se = np.sqrt(np.diag(np.linalg.inv(np.einsum("k,kij->ij", np.array(a.revolutions), F))))
    assert se == pytest.approx(a.std_errors, rel=1e-9)
    # frequency_list.predict with one count per ratio (in any order) says the same
    p = DesignProblem(spec, theta(spec), SPIN, RADIUS, U, 50)
    assert predict(p, a.ratios[::-1], a.revolutions[::-1]).std_errors == pytest.approx(a.std_errors, rel=1e-9)
    assert np.all(se <= scales * (1 + 1e-9)) and a.worst <= 1 + 1e-9
    # the same ratios with one count for all that reaches the target costs more rig time
    n_even = 1
    while np.any(np.sqrt(np.diag(np.linalg.inv(n_even * F.sum(axis=0)))) > scales):
        n_even += 1
    tau = revolution_time(a.ratios, SPIN)
    assert a.acquisition_s < n_even * tau.sum()
    # and the paper's list (the reference it was asked to match) costs more than twice as much
    paper = 50 * revolution_time(PAPER, SPIN).sum() + 2 * 2.05 * len(PAPER)
    assert a.rig_time_s < 0.55 * paper
    assert min(a.revolutions) >= 10
    with pytest.raises(ReductionError, match="these ratios cannot identify the model"):
        allocate(spec, theta(spec), SPIN, RADIUS, [0.5], U, scales)
    # a constraint no list of the ratios passes is said as that, not as identifiability
    with pytest.raises(ReductionError, match="the list constraint refuses even all these ratios together"):
        allocate(spec, theta(spec), SPIN, RADIUS, PAPER, U, scales, admissible=lambda r: r.size > len(PAPER))


def test_time_shares_sum_to_one_and_beat_the_even_split():
    spec = model_spec("kcd11")
    F = revolution_information(spec, theta(spec), SPIN, RADIUS, PAPER, U)
    tau = revolution_time(PAPER, SPIN)
    s = paper_errors(spec)
    w, T = time_shares(F, tau, s)
    assert w.sum() == pytest.approx(1.0) and np.all(w >= 0)
    even = np.full(len(PAPER), 1 / len(PAPER))
    T_even = np.max(np.diag(np.linalg.inv(np.einsum("k,kij->ij", even / tau, F * np.outer(s, s)))))
    assert T < T_even


def test_allocated_counts_give_the_predicted_spread():
    """Monte Carlo: 1000 tables at the allocated ratios and counts with complex Gaussian
    phasor noise of u / sqrt(n); the spread of every identified coefficient matches the
    allocation's predicted standard error within 15 % (1000 runs: 1 sigma about 2.2 %)."""
    spec = model_spec("kcd11")
    th = theta(spec)
    a = allocate(spec, th, SPIN, RADIUS, allowed_ratios(0.2, 1.5), U, paper_errors(spec), block_overhead=2.05)
    r = np.array(a.ratios)
    orbit, x, y = design_orbits(r * SPIN / (2 * math.pi), "both", RADIUS)
    n = np.repeat(np.array(a.revolutions, float), 2)
    fx, fy = forces(impedance(spec, th, orbit), x, y)
    u = U[None, :] / np.sqrt(n)[:, None]
    rng = np.random.default_rng(4)
    est = []
    for _ in range(1000):
        noise = [
            u[:, c] * (rng.standard_normal(n.size) + 1j * rng.standard_normal(n.size)) / math.sqrt(2) for c in range(4)
        ]
        table = OrbitTable(
            SPIN, orbit, x + noise[0], y + noise[1], fx + noise[2], fy + noise[3], n_records=n.astype(int), u=u
        )
        est.append(identify(table, "kcd11", method="wls").theta)
    spread = np.std(np.array(est), axis=0, ddof=1)
    assert spread / a.std_errors == pytest.approx(np.ones(spec.n_coefficients), abs=0.15)


# ------------------------------------------------------------------ what a model leaves out
def test_a_missing_d_moves_k_by_the_change_in_omega_squared():
    """kc8 on the forces of D alone (K = C = 0 in kcd12): at one frequency its K reads
    -Omega^2 D exactly, so from ratio 0.3 to ratio 1.5 K moves by -(1.5^2 - 0.3^2) omega^2 D;
    its uncertainty follows D's."""
    from reduction.misfit import list_shift

    small, rich = model_spec("kc8"), model_spec("kcd12")
    theta = np.zeros(rich.n_coefficients)
    d = {"Dxx": 40.0, "Dyy": 30.0}
    for name, v in d.items():
        theta[rich.names.index(name)] = v
    cov = np.zeros((rich.n_coefficients, rich.n_coefficients))
    cov[rich.names.index("Dxx"), rich.names.index("Dxx")] = 5.0**2
    sh = list_shift(small, rich, theta, cov, SPIN, RADIUS, ([0.3], 50, U), ([1.5], 200, U))
    dw2 = (1.5**2 - 0.3**2) * SPIN**2
    assert sh.shift[small.names.index("Kxx")] == pytest.approx(-dw2 * 40.0, rel=1e-9)
    assert sh.shift[small.names.index("Kyy")] == pytest.approx(-dw2 * 30.0, rel=1e-9)
    assert sh.std[small.names.index("Kxx")] == pytest.approx(dw2 * 5.0, rel=1e-9)
    assert np.allclose(sh.shift[4:], 0.0, atol=1e-6)  # C is not touched by D
    same = list_shift(small, rich, theta, cov, SPIN, RADIUS, ([0.3], 50, U), ([0.3], 200, U))
    assert np.allclose(same.shift, 0.0, atol=1e-6)  # the same frequency: nothing moves
