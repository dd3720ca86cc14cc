"""Simulator configuration: SimConfig dataclasses and the TOML loader.

Fields are SI (m, N, s, rad, Pa, K). In a TOML file a key may instead carry
an edge unit as a suffix, converted on load: ``_deg`` (degrees -> rad),
``_um`` (micrometres -> m), ``_mpa`` (MPa -> Pa), ``_kpa`` (kPa -> Pa),
``_degc`` (degC -> K). Example: ``trigger_phase_deg = 20`` sets
``AdcConfig.trigger_phase`` to 0.349 rad. See config/sim.toml.

Defaults: a 4-pocket oil-fed hydrostatic journal bearing, D = 60 mm,
radial clearance c = 60 um, K ~ 3e7 N/m, C ~ 8e4 N s/m, D ~ 1 kg.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

Matrix = tuple[tuple[float, float], tuple[float, float]]

CHANNEL_NAMES = ("fx_piezo", "fy_piezo", "fx_strain", "fy_strain", "x_a", "y_a", "x_b", "y_b")
CHANNEL_GAINS = (0.1, 0.1, 0.1, 0.1, 5e-9, 5e-9, 5e-9, 5e-9)  # unit/count, docs/architecture.md


def _zeros() -> Matrix:
    return ((0.0, 0.0), (0.0, 0.0))


@dataclass
class BearingConfig:
    """True bearing coefficients.

    K(omega, Omega) = K0 * p + omega * K_spin + |Omega|^m K_orbit
    C(Omega) = C0 + |Omega|^n C_orbit;  D(Omega) = D0 + |Omega|^p D_orbit
    (omega spin, Omega orbit in rad/s; p the hydrostatic pressure scale,
    1 at the reference supply setting when ``pressure_scaling``).
    Second-harmonic nonlinearity: f_nl = -(nonlinear * Kxx0 / c) *
    (dx^2 - dy^2, 2 dx dy) for the dynamic displacement d.
    """

    K0: Matrix = ((3.0e7, 0.0), (0.0, 3.3e7))  # N/m
    K_spin: Matrix = ((0.0, 4.0e4), (-4.0e4, 0.0))  # N/m per rad/s of spin
    C0: Matrix = ((8.0e4, 2.0e3), (2.0e3, 8.6e4))  # N s/m
    D0: Matrix = ((1.0, 0.05), (0.05, 1.1))  # kg
    K_orbit: Matrix = field(default_factory=_zeros)  # N/m per (rad/s)^m
    C_orbit: Matrix = field(default_factory=_zeros)  # N s/m per (rad/s)^n
    D_orbit: Matrix = field(default_factory=_zeros)  # kg per (rad/s)^p
    orbit_exponents: tuple[int, int, int] = (1, 1, 1)  # m, n, p
    nonlinear: float = 0.1  # second-harmonic stiffness / Kxx0 (at d = c)
    pressure_scaling: bool = True  # K0 scales with p_recess * (1 - beta)


@dataclass
class GeometryConfig:
    """Journal orbit and probe geometry (SI)."""

    clearance: float = 60e-6  # radial clearance c, m
    diameter: float = 0.060  # m (informational)
    orbit_ratio: float = 0.1  # eps_d: orbit radius R = eps_d * c
    static_eccentricity: float = 0.2  # eps_s: static offset eps_s * c
    static_angle: float = -math.pi / 2  # rad, direction of the static offset (load down)
    ellipticity: float = 0.02  # x semi-axis R(1+e), y semi-axis R(1-e)
    probe_tilt: float = 0.05  # conical motion at the probe planes, fraction of R (+A, -B)
    probe_tilt_phase: float = math.radians(30.0)  # rad
    probe_misalignment: float = math.radians(0.3)  # rad, angle between the probe planes' axes


@dataclass
class AdcConfig:
    """A/D board: scan list, calibration, framing, trigger."""

    mode: str = "sequential"  # sequential | simultaneous
    channels: tuple[str, ...] = CHANNEL_NAMES
    gains: tuple[float, ...] = CHANNEL_GAINS
    offsets: tuple[float, ...] = (0.0,) * 8
    frame_slots: int = 45  # slots per frame, 1..255
    trigger_phase: float = math.radians(20.0)  # rad, phase phi0 of x at the trigger


@dataclass
class LmsConfig:
    """Calibration errors of the two load measuring systems (reading = g e^{-i lag} f)."""

    piezo_gain_error: float = 0.0
    piezo_phase_lag: float = 0.0  # rad
    strain_gain_error: float = 0.02
    strain_phase_lag: float = math.radians(0.3)


@dataclass
class NoiseConfig:
    """Disturbances (all off when ``enabled`` is false)."""

    enabled: bool = True
    piezo_white: float = 1.0  # N rms
    strain_white: float = 1.5  # N rms
    probe_white: float = 20e-9  # m rms
    runout: tuple[float, ...] = (0.4e-6, 0.15e-6)  # m, spin harmonics 1, 2, ... at the probes
    bearing_orders: tuple[float, ...] = (3.05, 4.95)  # ball-pass orders of the spindle bearings
    bearing_force: float = 1.5  # N per order, force channels
    bearing_probe: float = 3e-9  # m per order, probe channels
    line_frequency: float = 50.0  # Hz (simulated time)
    line_force: float = 0.4  # N
    line_probe: float = 8e-9  # m
    encoder_jitter: float = math.radians(0.02)  # rad rms slot-edge error
    speed_ripple: float = 3e-4  # relative speed ripple of both spindles
    ripple_frequency: float = 7.7  # Hz (simulated time)


@dataclass
class SupplyConfig:
    """Lubricant supply; recess pressure and beta are the operator's manual settings."""

    recess_pressure: float = 1.0e6  # Pa, mean recess pressure
    pressure_ratio: float = 0.5  # beta = p_recess / p_supply
    t_supply: float = 313.15  # K
    heating: float = 1.0e-4  # K per (rad/s)^2 of spin, recess temperature rise
    orifice_diameter: float = 1.0e-3  # m
    discharge_coefficient: float = 0.7
    density: float = 860.0  # kg/m^3


@dataclass
class SimConfig:
    bearing: BearingConfig = field(default_factory=BearingConfig)
    geometry: GeometryConfig = field(default_factory=GeometryConfig)
    adc: AdcConfig = field(default_factory=AdcConfig)
    lms: LmsConfig = field(default_factory=LmsConfig)
    noise: NoiseConfig = field(default_factory=NoiseConfig)
    supply: SupplyConfig = field(default_factory=SupplyConfig)
    speedup: float = 1.0
    seed: int = 1

    def __post_init__(self) -> None:
        problems = validate(self)
        if problems:
            raise ValueError("invalid simulator configuration: " + "; ".join(problems))


def validate(cfg: SimConfig) -> list[str]:
    """Consistency problems of a configuration (empty when valid)."""
    p = []
    a = cfg.adc
    if a.mode not in ("sequential", "simultaneous"):
        p.append(f"adc.mode must be 'sequential' or 'simultaneous', got {a.mode!r}")
    n = len(a.channels)
    if n < 1 or (a.mode != "simultaneous" and 360 % n):  # spec: C must divide 360 (sequential scan)
        p.append(f"adc.channels: the channel count must divide 360 in sequential mode, got {n}")
    unknown = [c for c in a.channels if c not in CHANNEL_NAMES]
    if unknown:
        p.append(f"adc.channels: unknown channel names {unknown}; known: {list(CHANNEL_NAMES)}")
    if len(a.gains) != n or len(a.offsets) != n:
        p.append("adc.gains and adc.offsets need one value per channel")
    if any(g == 0 for g in a.gains):
        p.append("adc.gains must be non-zero")
    if not 1 <= a.frame_slots <= 255:
        p.append(f"adc.frame_slots must be 1..255, got {a.frame_slots}")
    if cfg.adc.mode == "simultaneous" and n * a.frame_slots * 2 > 65000:
        p.append("adc.frame_slots too large for simultaneous mode")
    if not cfg.geometry.clearance > 0:
        p.append("geometry.clearance must be > 0")
    if not 0 < cfg.supply.pressure_ratio < 1:
        p.append("supply.pressure_ratio must be in (0, 1)")
    if not cfg.speedup > 0:
        p.append("speedup must be > 0")
    return p


_SUFFIXES = {
    "_deg": lambda v: math.radians(v),
    "_um": lambda v: v * 1e-6,
    "_mpa": lambda v: v * 1e6,
    "_kpa": lambda v: v * 1e3,
    "_degc": lambda v: v + 273.15,
}


def _convert(value, fn):
    if isinstance(value, list):
        return [_convert(v, fn) for v in value]
    return fn(value)


def _to_field_type(value):
    if isinstance(value, list):
        return tuple(_to_field_type(v) for v in value)
    return value


def _section(cls, table: dict, where: str, problems: list[str]):
    names = {f.name: f for f in dataclasses.fields(cls)}
    kwargs = {}
    for key, value in table.items():
        name, fn = key, None
        if key not in names:
            for suffix, conv in _SUFFIXES.items():
                if key.endswith(suffix) and key[: -len(suffix)] in names:
                    name, fn = key[: -len(suffix)], conv
                    break
            else:
                problems.append(f"unknown key '{where}{key}'")
                continue
        try:
            kwargs[name] = _to_field_type(_convert(value, fn) if fn else value)
        except TypeError:
            problems.append(f"key '{where}{key}': expected numbers, got {value!r}")
    return kwargs


def load_sim_config(path: str | Path) -> SimConfig:
    """Read a SimConfig from TOML. Raises ValueError naming the file and key."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as err:
        raise ValueError(f"{path}: {err}") from err
    problems: list[str] = []
    classes = {
        "bearing": BearingConfig, "geometry": GeometryConfig, "adc": AdcConfig,
        "lms": LmsConfig, "noise": NoiseConfig, "supply": SupplyConfig,
    }
    kwargs = {}
    for key, value in data.items():
        if key in classes:
            if not isinstance(value, dict):
                problems.append(f"'{key}' must be a table")
                continue
            kwargs[key] = classes[key](**_section(classes[key], value, f"{key}.", problems))
        elif key in ("speedup", "seed"):
            kwargs[key] = value
        else:
            problems.append(f"unknown key '{key}'")
    if problems:
        raise ValueError(f"{path}: " + "; ".join(problems))
    try:
        return SimConfig(**kwargs)
    except (TypeError, ValueError) as err:
        raise ValueError(f"{path}: {err}") from err
