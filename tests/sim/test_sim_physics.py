"""Bearing physics and configuration (pure, no I/O)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.config import NoiseConfig, SimConfig
from sim.scenario_files import load_sim_config
from sim.physics import RigPhysics

NAMES = ["fx_piezo", "fy_piezo", "fx_strain", "fy_strain", "x_a", "y_a", "x_b", "y_b"]


def quiet(scenario: str = "config/sim.toml", **geometry) -> RigPhysics:
    cfg = load_sim_config(scenario)
    cfg.noise = NoiseConfig(enabled=False)
    for k, v in geometry.items():
        setattr(cfg.geometry, k, v)
    return RigPhysics(cfg)


def sampled_harmonics(ph: RigPhysics, spin: float, orbit: float, n: int = 720, h: int = 1) -> dict:
    """Harmonic h of the time-domain signals on a uniform grid of n angles."""
    theta = 2 * np.pi * np.arange(n) / n
    t = theta / abs(orbit)
    out = {}
    for k, name in enumerate(NAMES):
        v = ph.channel_values(k, theta, t, spin * t, np.full(n, orbit), spin, orbit)
        out[name] = complex(2 / n * np.sum(v * np.exp(-1j * h * theta)))
    return out


@pytest.mark.parametrize("orbit", [2 * math.pi * 25, -2 * math.pi * 25, 2 * math.pi * 3])
def test_time_domain_reproduces_analytic_phasors(orbit):
    """Linearised bearing, ideal chain, circular orbit, aligned probes: f_bar = -Z d_bar
    with x_bar = R e^{i phi0}, y_bar = -sign(Omega) i R e^{i phi0}, to 1e-9."""
    ph = quiet("config/sim/clean.toml", ellipticity=0.0, probe_tilt=0.0, probe_misalignment=0.0)
    spin = 180.0
    got = sampled_harmonics(ph, spin, orbit)
    R = 0.04 * 60e-6
    E = np.exp(1j * math.radians(20.0))
    d = np.array([R * E, -1j * np.sign(orbit) * R * E])
    f = -ph.impedance(spin, orbit) @ d
    g = 1.018 * np.exp(-1j * math.radians(0.3))
    want = dict(zip(NAMES, [f[0], f[1], g * f[0], g * f[1], d[0], d[1], d[0], d[1]]))
    for name in NAMES:
        assert abs(got[name] - want[name]) <= 1e-9 * abs(want[name]), name


@pytest.mark.parametrize("orbit", [2 * math.pi * 17, -2 * math.pi * 17])
def test_true_phasors_match_the_signals_with_full_geometry(orbit):
    ph = quiet()  # nonlinear film, chain errors, ellipse, conical tilt, misaligned probe planes
    got = sampled_harmonics(ph, 90.0, orbit)
    true = ph.true_phasors(90.0, orbit)
    for name in NAMES:
        assert abs(got[name] - true[name]) <= 1e-9 * abs(true[name]), name
    # the mean of the two probe planes cancels the conical tilt, up to the planes'
    # misalignment (0.3 deg) times the tilt (5 %) ~1.3e-4, and reads the orbit through
    # the probes' sensitivity errors (-1 %, +0.3 % / +0.1 %) and the filter (f << f_c)
    x = (true["x_a"] + true["x_b"]) / 2
    R = 0.04 * 60e-6
    assert abs(x) == pytest.approx(R * 1.02 * 0.99 * 1.002, rel=3e-4)


def test_large_orbits_show_the_film_nonlinearity():
    """Small orbits follow the linearised bearing; at eps_d = 0.3 the fundamental
    departs from -Z d by several percent and odd harmonics grow (a centred journal
    keeps the force odd in the displacement: no even harmonics); a static offset
    breaks that symmetry and brings the second harmonic."""
    ph = quiet(ellipticity=0.0, probe_tilt=0.0, probe_misalignment=0.0)
    spin, orbit, c = 104.7, 2 * math.pi * 10, 60e-6

    def departure(eps_d: float, eps_s: float = 0.0):
        ph.set_manual(orbit_radius=eps_d * c, static_eccentricity=eps_s)
        F = ph.force_harmonics(spin, orbit)
        R = eps_d * c
        lin = -ph.impedance(spin, orbit) @ np.array([R, -1j * R])
        return np.max(np.abs(F[:, 1] - lin) / np.abs(lin)), np.abs(F[0, 2:4]) / np.abs(F[0, 1])

    small, (h2, h3) = departure(0.04)
    assert small < 5e-3 and h2 < 1e-12 and h3 < 2e-3
    large, (h2, h3) = departure(0.3)
    assert large > 0.05 and h2 < 1e-12 and h3 > 0.01
    _, (h2, _) = departure(0.15, eps_s=0.3)
    assert h2 > 0.005


def test_manual_settings_are_checked():
    ph = quiet(probe_tilt=0.0, probe_misalignment=0.0)
    with pytest.raises(ValueError, match="clearance"):
        ph.set_manual(orbit_radius=60e-6)
    with pytest.raises(ValueError, match="pressure_ratio"):
        ph.set_manual(pressure_ratio=1.2)
    ph.set_manual(orbit_radius=12e-6, static_eccentricity=0.0)
    p = ph.true_phasors(0.0, 10.0)
    assert abs(p["x_a"] + p["x_b"]) / 2 == pytest.approx(12e-6 * 1.02 * 0.99 * 1.002, rel=1e-3)


def test_supply_state_responds_to_the_operating_point():
    """Centred journal at rest: every recess at p_r, supply p_r / beta, and the flow
    through the lands 4 B_f c^3 p_r / mu (B_f the land flow factor, by hand)."""
    ph = quiet(static_eccentricity=0.0)
    a = ph.aux_state(0.0, 0.0)
    assert a["p_supply"] == pytest.approx(0.4826e6 / 0.25)
    np.testing.assert_allclose(a["p_recess"], 0.4826e6, rtol=1e-12)
    assert a["beta"] == pytest.approx(0.25)
    R, L, l, th = 0.01905, 0.0381, 0.034, math.radians(78)
    l_a, l_c = (L - l) / 2, R * (math.pi / 2 - th) / 2
    B_f = (2 * R * th / l_a + 2 * l / l_c) / 12
    assert a["flow"] == pytest.approx(4 * B_f * 60e-6**3 * 0.4826e6 / 0.098, rel=1e-9)
    hot = ph.aux_state(250.0, 0.0)
    assert hot["t_recess"] > hot["t_groove"] > hot["t_supply"] == a["t_supply"]
    ph.set_manual(recess_pressure=1.0342e6)
    assert ph.aux_state(0.0, 0.0)["flow"] > a["flow"]
    # the journal sits low (static offset along -y): the bottom recess (270 deg) is highest
    ph.set_manual(static_eccentricity=0.3)
    assert np.argmax(ph.aux_state(0.0, 0.0)["p_recess"]) == 3


def test_config_file_with_edge_units(tmp_path):
    p = tmp_path / "sim.toml"
    p.write_text(
        "speedup = 4\n[geometry]\nclearance_um = 80\n[adc]\ntrigger_phase_deg = 45\n"
        'mode = "simultaneous"\n[supply]\nrecess_pressure_mpa = 1.5\nt_supply_degc = 50\n'
    )
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
    assert load_sim_config("config/sim.toml") == SimConfig()


@pytest.mark.parametrize("name", ["clean", "compressible"])
def test_scenarios_load_and_differ_from_the_default_where_they_say(name):
    cfg = load_sim_config(f"config/sim/{name}.toml")
    ref = SimConfig()
    assert cfg.adc == ref.adc and cfg.geometry == ref.geometry and cfg.supply == ref.supply
    if name == "clean":
        assert not cfg.bearing.compressible and cfg.bearing.linear and not cfg.chain.enabled
    else:
        assert cfg.bearing.bulk_modulus < ref.bearing.bulk_modulus and cfg.chain == ref.chain


def test_film_and_channel_harmonics_are_shared_across_seeds_not_configurations():
    """A Monte Carlo over seeds solves each operating point's film once: a physics with another
    seed gets the same (read-only) harmonics; another viscosity, a calibration load or another
    orbit radius get their own."""
    cfg = load_sim_config("config/sim.toml")
    spin, orbit = 104.7, -2 * math.pi * 13.7
    a = RigPhysics(cfg)
    F, q = a.force_harmonics(spin, orbit), a.channel_harmonics(0, spin, orbit)
    cfg.seed += 1
    b = RigPhysics(cfg)
    assert b.force_harmonics(spin, orbit) is F and b.channel_harmonics(0, spin, orbit) is q
    assert not F.flags.writeable and not q.flags.writeable
    b.apply_load(5.0, 0.0)
    assert b.channel_harmonics(0, spin, orbit)[0] == pytest.approx(q[0] + 5.0 * (1 + b.chains[0].gain))
    b.set_manual(orbit_radius=0.08 * cfg.geometry.clearance)
    assert abs(b.force_harmonics(spin, orbit)[0, 1]) > 1.5 * abs(F[0, 1])
    cfg.bearing.viscosity *= 2
    c = RigPhysics(cfg)
    assert abs(c.force_harmonics(spin, orbit)[0, 1] - F[0, 1]) > 0.1 * abs(F[0, 1])
