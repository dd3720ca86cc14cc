"""The hydrostatic bearing against limits a reviewer can check by hand.

Geometry of config/sim.toml: journal R = 19.05 mm, L = 38.1 mm, recess l = 34 mm
over 78 deg, 0.3 mm deep, c = 60 um, mu = 0.098 Pa s. Derived by hand (docs/simulator.md):
    lands        l_a = (L - l)/2, l_c = R (pi/2 - theta_r)/2
    flow factor  B_f = (2 R theta_r / l_a + 2 l / l_c) / 12,  G(c) = B_f c^3 / mu
    area         A_e = (l + l_a) 2 R sin(theta_e / 2),  theta_e = theta_r + l_c / R
    per recess   Q = G p_r, total conductance G_p = Q (2 - beta) / (2 p_r (1 - beta))
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from sim.config import SimConfig
from sim.physics import RigPhysics

R, L, l, TH, c, MU = 0.01905, 0.0381, 0.034, math.radians(78.0), 60e-6, 0.098
L_A, L_C = (L - l) / 2, R * (math.pi / 2 - TH) / 2
B_F = (2 * R * TH / L_A + 2 * l / L_C) / 12
A_E = (l + L_A) * 2 * R * math.sin((TH + L_C / R) / 2)
PR, BETA = 0.4826e6, 0.25


def physics(*, compressible=True, inertia=False, **bearing) -> RigPhysics:
    cfg = SimConfig()
    cfg.bearing = dataclasses.replace(cfg.bearing, compressible=compressible, fluid_inertia=inertia, **bearing)
    return RigPhysics(cfg)


def g_p(p_r=PR, beta=BETA) -> float:
    q = B_F * c**3 * p_r / MU
    return q * (2 - beta) / (2 * p_r * (1 - beta))


@pytest.mark.parametrize("p_r, beta", [(0.4826e6, 0.25), (1.0342e6, 0.4), (1.0342e6, 0.55)])
def test_orifice_compensated_stiffness_at_rest_and_zero_frequency(p_r, beta):
    """K = 12 A_e p_r (1 - beta) / ((2 - beta) c) on both axes, no cross terms, no damping at w -> 0."""
    ph = physics()
    ph.set_manual(recess_pressure=p_r, pressure_ratio=beta, static_eccentricity=0.0)
    Z = ph.impedance(0.0, 1e-9)
    K = 12 * A_E * p_r * (1 - beta) / ((2 - beta) * c)
    assert 1e7 < K < 1e8
    np.testing.assert_allclose(Z.real, K * np.eye(2), rtol=1e-9, atol=1e-9 * K)
    assert np.all(np.abs(Z.imag) < 1e-9 * K)


@pytest.mark.parametrize("spin", [52.4, 104.7, 209.4])
def test_couette_cross_coupling_sign_and_magnitude(spin):
    """K_xy = -K_yx = 2 A_e U l sin(theta_r/2) / G_p, U = omega R, growing linearly with spin;
    positive: a journal displaced along +x is pushed along +y, the direction of rotation."""
    ph = physics()
    ph.set_manual(static_eccentricity=0.0)
    Z0, Z = ph.impedance(0.0, 1e-9).real, ph.impedance(spin, 1e-9).real
    k = 2 * A_E * spin * R * l * math.sin(TH / 2) / g_p()
    assert Z[0, 1] == pytest.approx(k, rel=1e-9) and Z[1, 0] == pytest.approx(-k, rel=1e-9)
    assert 0.02 < k / Z0[0, 0] < 0.5
    np.testing.assert_allclose(np.diag(Z), np.diag(Z0), rtol=1e-12)  # centred: spin leaves the diagonal
    f = -Z @ np.array([1e-6, 0.0])
    assert f[1] > 0 and f[0] < 0


def test_compressibility_corner_frequency():
    """Zero spin, no inertia: Z_xx(w) = K0 (1 + i w / w_z) / (1 + i w / w_c) with the recess
    corner w_c = G_p B / V (V recess + feed volume) and w_z = K0 / C0 = 3 Q / (c A_s), A_s = A_e."""
    ph = physics(bulk_modulus=1e8, feed_volume=2.5e-6)
    ph.set_manual(static_eccentricity=0.0)
    V = R * TH * l * 0.3e-3 + 2.5e-6
    w_c = g_p() * 1e8 / V
    K0 = 12 * A_E * PR * (1 - BETA) / ((2 - BETA) * c)
    w_z = 3 * B_F * c**3 * PR / MU / (c * A_E)
    assert 100 < w_c < 1000
    for w in (0.1 * w_c, w_c, 3 * w_c):
        Z = ph.impedance(0.0, w)[0, 0]
        assert Z == pytest.approx(K0 * (1 + 1j * w / w_z) / (1 + 1j * w / w_c), rel=1e-9)
    # at the corner the pressure lags the squeeze by 45 deg: the damping has fallen a lot
    C_corner = ph.impedance(0.0, w_c)[0, 0].imag / w_c
    assert C_corner < 0.6 * K0 / w_z


def test_compressibility_off_gives_constant_coefficients():
    """B -> infinity: Z = K + i w C - w^2 M exactly, M = pi rho R L^3 / (12 c) the film's added mass."""
    ph = physics(compressible=False, inertia=True)
    w = np.linspace(10.0, 150.0, 8)
    Z = ph.impedances(104.7, w)
    M = np.pi * 870 * R * L**3 / (12 * c)
    K, C = Z[0].real + w[0] ** 2 * M * np.eye(2), Z[0].imag / w[0]
    want = K[None] + 1j * w[:, None, None] * C[None] - (w * w)[:, None, None] * M * np.eye(2)
    np.testing.assert_allclose(Z, want, rtol=1e-12, atol=1e-6)


def test_ninety_degree_rotation_symmetry_of_the_centred_journal():
    """Centred journal: rotating the displacement by 90 deg rotates the force by 90 deg,
    both for the linearised Z (Z = Q Z Q^T) and for the nonlinear film on a large orbit."""
    ph = physics()
    ph.set_manual(static_eccentricity=0.0)
    Q = np.array([[0.0, -1.0], [1.0, 0.0]])
    for w in (20.0, 120.0):
        Z = ph.impedance(104.7, w)
        np.testing.assert_allclose(Q @ Z @ Q.T, Z, rtol=1e-12, atol=1e-9 * np.abs(Z).max())
    b, n, wo = ph.bearing, 64, 60.0
    psi = 2 * np.pi * np.arange(n) / n
    r = 0.3 * c

    def path(ph0):
        a = psi + ph0
        return (
            r * np.cos(a),
            r * np.sin(a),
            -r * wo * np.sin(a),
            r * wo * np.cos(a),
            -r * wo**2 * np.cos(a),
            -r * wo**2 * np.sin(a),
        )

    f0 = b.periodic_force(*path(0.0), wo, 104.7, ph.supply)
    f90 = b.periodic_force(*path(np.pi / 2), wo, 104.7, ph.supply)
    np.testing.assert_allclose(f90, Q @ f0, atol=1e-9 * np.abs(f0).max())


def test_pressure_settings_and_static_eccentricity_change_the_response():
    ph = physics()
    ph.set_manual(static_eccentricity=0.0)
    Z = ph.impedance(104.7, 50.0)
    ph.set_manual(recess_pressure=1.0342e6)
    assert ph.impedance(104.7, 50.0)[0, 0].real > 1.5 * Z[0, 0].real
    ph.set_manual(recess_pressure=PR, static_eccentricity=0.3)  # journal sits low, towards recess 270 deg
    Ze = ph.impedance(104.7, 50.0)
    assert Ze[1, 1].real > 1.05 * Z[1, 1].real and Ze[1, 1].imag > 1.05 * Z[1, 1].imag
    ph.set_manual(static_eccentricity=0.0, recess_pressure=0.0)  # pump off: squeeze film only
    Zoff = ph.impedance(104.7, 50.0)
    assert np.all(np.isfinite(Zoff)) and abs(Zoff[0, 0].real) < 0.01 * Z[0, 0].real
    ph.set_manual(recess_pressure=PR, orbit_radius=0.15 * c)  # a larger orbit: a larger force
    assert abs(ph.true_phasors(104.7, 50.0)["fx_piezo"]) > 3.5 * abs(Z[0, 0]) * 0.04 * c


def test_direction_does_not_change_the_impedance():
    ph = physics()
    np.testing.assert_array_equal(ph.impedance(104.7, -70.0), ph.impedance(104.7, 70.0))


@pytest.mark.parametrize("compressible", [False, True])
def test_reversed_spin_flips_the_cross_coupled_terms(compressible):
    """Spin -omega reverses the Couette flow: centred, K_xy(-omega) = -K_xy(omega) =
    -2 A_e U l sin(theta_r/2) / G_p (incompressible, w -> 0), the direct terms unchanged; the
    whole Z(Omega) is the mirror Z(-omega) = S Z(omega) S with S = diag(1, -1) (x -> x, y -> -y
    turns +omega into -omega), also in the nonlinear film force of a small orbit."""
    ph = physics(compressible=compressible)
    ph.set_manual(static_eccentricity=0.0)
    spin = 104.7
    k = 2 * A_E * spin * R * l * math.sin(TH / 2) / g_p()
    if not compressible:
        Z = ph.impedance(-spin, 1e-9).real
        assert Z[0, 1] == pytest.approx(-k, rel=1e-9) and Z[1, 0] == pytest.approx(k, rel=1e-9)
    S = np.diag([1.0, -1.0])
    w = np.array([30.0, 80.0, 130.0])
    zp, zm = ph.impedances(spin, w), ph.impedances(-spin, w)
    np.testing.assert_allclose(zm, S @ zp @ S, rtol=1e-12, atol=1e-12 * np.abs(zp).max())
    assert np.all(np.sign(zm[:, 0, 1].real) == -np.sign(zp[:, 0, 1].real))
    ph.set_manual(orbit_radius=0.01 * c)  # small orbit: the film force is nearly linear
    a, b = ph._orbit_axes()
    for s in (spin, -spin):
        F = ph.force_harmonics(s, 80.0)[:, 1]
        lin = -ph.impedance(s, 80.0) @ np.array([a, -1j * b])
        np.testing.assert_allclose(F, lin, rtol=2e-3, atol=2e-3 * np.abs(lin).max())
