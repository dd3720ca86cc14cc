"""Bearing physics and configuration (pure, no I/O)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.config import NoiseConfig, SimConfig, load_sim_config
from sim.physics import RigPhysics

NAMES = ["fx_piezo", "fy_piezo", "fx_strain", "fy_strain", "x_a", "y_a", "x_b", "y_b"]


def quiet(**geometry) -> RigPhysics:
    cfg = SimConfig()
    cfg.noise = NoiseConfig(enabled=False)
    for k, v in geometry.items():
        setattr(cfg.geometry, k, v)
    return RigPhysics(cfg)


def sampled_phasors(ph: RigPhysics, spin: float, orbit: float, n: int = 720) -> dict:
    """Fundamental of the time-domain signals on a uniform grid of n angles."""
    theta = 2 * np.pi * np.arange(n) / n
    t = theta / abs(orbit)
    out = {}
    for k, name in enumerate(NAMES):
        v = ph.channel_values(k, theta, t, spin * t, np.full(n, orbit), spin, orbit)
        out[name] = complex(2 / n * np.sum(v * np.exp(-1j * theta)))
    return out


@pytest.mark.parametrize("orbit", [2 * math.pi * 25, -2 * math.pi * 25, 2 * math.pi * 3])
def test_time_domain_reproduces_analytic_phasors(orbit):
    """Circular orbit, aligned probes: f_bar = -Z d_bar with x_bar = R e^{i phi0},
    y_bar = -sign(Omega) i R e^{i phi0}, to 1e-9 (before quantisation)."""
    ph = quiet(ellipticity=0.0, probe_tilt=0.0, probe_misalignment=0.0)
    spin = 180.0
    got = sampled_phasors(ph, spin, orbit)
    R = 0.1 * 60e-6
    E = np.exp(1j * math.radians(20.0))
    d = np.array([R * E, -1j * np.sign(orbit) * R * E])
    K, C, D = (np.array(m) for m in (
        [[3.0e7, 4.0e4 * spin], [-4.0e4 * spin, 3.3e7]],
        [[8.0e4, 2.0e3], [2.0e3, 8.6e4]],
        [[1.0, 0.05], [0.05, 1.1]]))
    w = abs(orbit)
    f = -(K + 1j * w * C - w * w * D) @ d
    g = 1.02 * np.exp(-1j * math.radians(0.3))
    want = dict(zip(NAMES, [f[0], f[1], g * f[0], g * f[1], d[0], d[1], d[0], d[1]]))
    for name in NAMES:
        assert abs(got[name] - want[name]) <= 1e-9 * abs(want[name]), name


@pytest.mark.parametrize("orbit", [2 * math.pi * 17, -2 * math.pi * 17])
def test_true_phasors_match_the_signals_with_full_geometry(orbit):
    ph = quiet()  # ellipse, conical tilt, misaligned probe planes, nonlinearity
    got = sampled_phasors(ph, 90.0, orbit)
    true = ph.true_phasors(90.0, orbit)
    for name in NAMES:
        assert abs(got[name] - true[name]) <= 1e-9 * abs(true[name]), name
    # the mean of the two probe planes cancels the conical tilt, up to the
    # planes' misalignment (0.3 deg) times the tilt (5 %): ~1.3e-4
    x = (true["x_a"] + true["x_b"]) / 2
    assert x == pytest.approx(0.1 * 60e-6 * 1.02 * np.exp(1j * math.radians(20)), rel=2e-4)


def test_second_harmonic_nonlinearity_leaves_the_fundamental_alone():
    ph = quiet(ellipticity=0.0)
    n, orbit = 720, 2 * math.pi * 10
    theta = 2 * np.pi * np.arange(n) / n
    v = ph.channel_values(0, theta, theta / orbit, 0 * theta, np.full(n, orbit), 0.0, orbit)
    f1 = abs(2 / n * np.sum(v * np.exp(-1j * theta)))
    f2 = abs(2 / n * np.sum(v * np.exp(-2j * theta)))
    R, c = 6e-6, 60e-6
    assert f2 == pytest.approx(0.1 * 3.0e7 / c * R * R, rel=1e-9)  # k2 R^2
    assert 0.005 < f2 / f1 < 0.02


def test_truth_cross_coupling_grows_with_spin_and_optional_orbit_dependence():
    cfg = SimConfig()
    cfg.bearing.K_orbit = ((1.0e3, 0.0), (0.0, 2.0e3))
    cfg.bearing.orbit_exponents = (2, 1, 1)
    ph = RigPhysics(cfg)
    K0, C0, D0 = ph.coefficients(0.0, 0.0)
    np.testing.assert_allclose(K0, [[3.0e7, 0], [0, 3.3e7]])
    K, C, D = ph.coefficients(250.0, -100.0)
    assert K[0, 1] == pytest.approx(1.0e7) and K[1, 0] == pytest.approx(-1.0e7)
    assert K[0, 0] == pytest.approx(3.0e7 + 1.0e3 * 100.0**2)  # |Omega|^m, sign-free
    np.testing.assert_allclose(C, [[8.0e4, 2.0e3], [2.0e3, 8.6e4]])
    np.testing.assert_allclose(D, D.T)
    # hydrostatic stiffness follows the supply: K0 ~ p_recess * (1 - beta)
    ph.set_manual(recess_pressure=2.0e6, pressure_ratio=0.5)
    assert ph.coefficients(0.0, 0.0)[0][0, 0] == pytest.approx(6.0e7)
    ph.set_manual(pressure_ratio=0.75)
    assert ph.coefficients(0.0, 0.0)[0][0, 0] == pytest.approx(3.0e7)


def test_manual_settings_are_checked():
    ph = quiet()
    with pytest.raises(ValueError, match="clearance"):
        ph.set_manual(orbit_radius=50e-6)
    with pytest.raises(ValueError, match="pressure_ratio"):
        ph.set_manual(pressure_ratio=1.2)
    ph.set_manual(orbit_radius=12e-6, static_eccentricity=0.0)
    p = ph.true_phasors(0.0, 10.0)
    assert abs(p["x_a"] + p["x_b"]) / 2 == pytest.approx(12e-6 * 1.02, rel=1e-3)


def test_supply_state_responds_to_the_operating_point():
    ph = quiet()
    a = ph.aux_state(0.0, 0.0)
    assert a["p_supply"] == pytest.approx(2.0e6)
    assert np.mean(a["p_recess"]) == pytest.approx(1.0e6)
    assert a["beta"] == pytest.approx(0.5)
    # the journal sits low (static offset along -y): the bottom pocket (270 deg) is highest
    assert np.argmax(a["p_recess"]) == 3
    assert 5.0 < a["flow"] * 60000 < 8.0  # L/min through four 1 mm orifices
    hot = ph.aux_state(250.0, 0.0)
    assert hot["t_recess"] > hot["t_groove"] > hot["t_supply"] == a["t_supply"]
    ph.set_manual(recess_pressure=2.0e6)
    assert ph.aux_state(0.0, 0.0)["flow"] > a["flow"]


def test_config_file_with_edge_units(tmp_path):
    p = tmp_path / "sim.toml"
    p.write_text('speedup = 4\n[geometry]\nclearance_um = 80\n[adc]\ntrigger_phase_deg = 45\n'
                 'mode = "simultaneous"\n[supply]\nrecess_pressure_mpa = 1.5\nt_supply_degc = 50\n')
    cfg = load_sim_config(p)
    assert cfg.speedup == 4 and cfg.geometry.clearance == pytest.approx(80e-6)
    assert cfg.adc.trigger_phase == pytest.approx(math.pi / 4) and cfg.adc.mode == "simultaneous"
    assert cfg.supply.recess_pressure == pytest.approx(1.5e6)
    assert cfg.supply.t_supply == pytest.approx(323.15)


def test_config_errors_name_file_and_key(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text("[geometry]\nclearence = 1\n[adc]\nframe_slots = 300\n")
    with pytest.raises(ValueError, match=r"bad\.toml.*geometry\.clearence"):
        load_sim_config(p)
    p.write_text("[adc]\nframe_slots = 300\n")
    with pytest.raises(ValueError, match=r"bad\.toml.*frame_slots"):
        load_sim_config(p)


def test_shipped_example_config_is_the_default():
    cfg = load_sim_config("config/sim.toml")
    ref = SimConfig()
    assert cfg.bearing == ref.bearing and cfg.adc.channels == ref.adc.channels
    assert cfg.adc.gains == ref.adc.gains
    assert cfg.geometry.static_angle == pytest.approx(ref.geometry.static_angle)
