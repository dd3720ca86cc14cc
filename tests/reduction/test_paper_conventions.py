"""The phasor and sign conventions against the paper's own equations, by hand.

Sawicki, Adams and Capaldi write f = -K d - C d' - D d'' (Eq. 1) and, for the forward circular
whirl with phi_x = 0, Eq. 7:
  f_x / R = -K_xx - Omega C_xy + Omega^2 D_xx + i (K_xy - Omega C_xx - Omega^2 D_xy)
  f_y / R = -K_yx - Omega C_yy + Omega^2 D_yx + i (K_yy - Omega C_yx - Omega^2 D_yy).
Those hold with the orbit-table contract's forward circle x_bar = R, y_bar = -i R (x = R cos,
y = R sin: from +x towards +y) and q = Re(q_bar e^{i Omega t}); backward whirl (y_bar = +i R)
flips the sign of every term that carries one factor of y_bar's i.
"""

from __future__ import annotations

import numpy as np
import pytest

from reduction.identify import identify
from reduction.impedance import forces
from reduction.table import OrbitTable
from reduction.whirl import whirl_sense

K = np.array([[3.0e7, 1.2e7], [-0.9e7, 2.5e7]])  # N/m: K_xy > 0 > K_yx, the Couette sense of a +x -> +y spin
C = np.array([[4.0e4, 3.0e3], [2.0e3, 5.0e4]])  # N s/m
D = np.array([[20.0, 5.0], [7.0, 30.0]])  # kg
R = 1e-5  # m


def _eq7(w: float, backward: bool = False) -> tuple[complex, complex]:
    """The paper's Eq. 7 written out term by term (s = -1 for backward whirl)."""
    s = -1.0 if backward else 1.0
    fx = (-K[0, 0] - s * w * C[0, 1] + w * w * D[0, 0]) + 1j * (s * K[0, 1] - w * C[0, 0] - s * w * w * D[0, 1])
    fy = (-K[1, 0] - s * w * C[1, 1] + w * w * D[1, 0]) + 1j * (s * K[1, 1] - w * C[1, 0] - s * w * w * D[1, 1])
    return R * fx, R * fy


@pytest.mark.parametrize("backward", [False, True])
def test_f_equals_minus_z_d_is_the_papers_equation_7(backward):
    w = 2 * np.pi * 7.3
    Z = K + 1j * w * C - w * w * D
    y = (1j if backward else -1j) * R
    fx, fy = forces(Z[None], np.array([R]), np.array([y]))
    want = _eq7(w, backward)
    assert fx[0] == pytest.approx(want[0], rel=1e-12) and fy[0] == pytest.approx(want[1], rel=1e-12)


def test_the_time_signals_of_the_forward_circle_turn_from_x_to_y_and_carry_eq_1():
    """Re(q_bar e^{i Omega t}) of x_bar = R, y_bar = -i R is (R cos, R sin); the force phasors of
    Eq. 7 are, sample by sample, -K d - C d' - D d'' (Eq. 1) of those signals."""
    w = 2 * np.pi * 7.3
    t = np.linspace(0.0, 2 * np.pi / w, 17)
    e = np.exp(1j * w * t)
    d = np.stack([np.real(R * e), np.real(-1j * R * e)])
    np.testing.assert_allclose(d, [R * np.cos(w * t), R * np.sin(w * t)], atol=1e-18)
    dd, ddd = w * np.stack([-R * np.sin(w * t), R * np.cos(w * t)]), -w * w * d
    f = -K @ d - C @ dd - D @ ddd
    fx, fy = _eq7(w)
    np.testing.assert_allclose(f, np.real(np.stack([fx * e, fy * e])), rtol=1e-9, atol=1e-9 * np.abs(f).max())


def test_identify_returns_the_signed_cross_coupled_terms_from_eq_7_forces():
    """Forces written from Eq. 7 (forward) and its backward form at three frequencies give back
    K, C and D, every cross-coupled sign included (kcd12: no symmetry imposed)."""
    rows = [(w, b) for w in 2 * np.pi * np.array([4.0, 9.0, 15.0]) for b in (False, True)]
    f = np.array([_eq7(w, b) for w, b in rows])
    table = OrbitTable(
        100.0,
        np.array([w for w, _ in rows]),
        np.full(len(rows), R, dtype=complex),
        np.array([(1j if b else -1j) * R for _, b in rows]),
        f[:, 0],
        f[:, 1],
    )
    assert list(table.forward()) == [True, False] * 3
    got = identify(table, "kcd12").coefficients
    for name, M in (("K", K), ("C", C), ("D", D)):
        for i, a in enumerate("xy"):
            for j, b in enumerate("xy"):
                assert got[f"{name}{a}{b}"] == pytest.approx(M[i, j], rel=1e-9), f"{name}{a}{b}"


def test_whirl_sense_of_circles_ellipses_and_lines_by_hand():
    """+1 the contract's forward circle (x_bar = R, y_bar = -i R), -1 the backward one, for any
    phase and radius; otherwise the sine of y's lag behind x (an ellipse on the axes: +-1); a line
    and no motion 0."""
    phase = np.exp(1j * np.array([0.0, 1.0, -2.5]))
    np.testing.assert_allclose(whirl_sense(R * phase, -1j * R * phase), 1.0, rtol=1e-12)
    np.testing.assert_allclose(whirl_sense(3 * R * phase, 3j * R * phase), -1.0, rtol=1e-12)
    a, b = 2 * R, R  # x = a cos, y = b sin: forward, y lags 90 deg, sense 1 whatever the axes
    assert whirl_sense(a, -1j * b) == pytest.approx(1.0)
    # x and y of equal amplitude, y lagging x by 30 deg: a forward ellipse of sense sin(30 deg)
    assert whirl_sense(R, R * np.exp(-1j * np.pi / 6)) == pytest.approx(0.5)
    assert whirl_sense(R, 0.5 * R) == 0.0 and whirl_sense(0.0, 0.0) == 0.0  # a line, no motion
    table = OrbitTable(1.0, [1.0, 2.0], [R, R], [-1j * R, 1j * R], [0j, 0j], [0j, 0j])
    assert list(table.forward()) == [True, False]
