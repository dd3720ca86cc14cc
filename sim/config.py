"""Simulator configuration: the SimConfig dataclasses and their validation. Fields are SI (m, N,
s, rad, Pa, K). Read from TOML, and the shipped scenarios by name: sim.scenario_files.

Defaults: the paper's rig at its Table 1 operating point: a four-recess,
orifice-compensated hydrostatic journal bearing with large recesses and
narrow lands, D = L = 38.1 mm, c = 60 um, SAE 30 oil; K ~ 4e7 N/m,
C ~ 1.2e5 N s/m, the film's inertia ~ 4 kg (the recesses' compressibility makes the apparent D
of a constant fit about -38 kg). orbitrig's shipped config/rig.toml [bearing] is this bearing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

Matrix = tuple[tuple[float, float], tuple[float, float]]

CHANNEL_NAMES = ("fx_piezo", "fy_piezo", "fx_strain", "fy_strain", "x_a", "y_a", "x_b", "y_b")
#: the displacement probes' channels (a name not starting with "f"), in CHANNEL_NAMES order: the order of
#: ChainConfig.probe_delay
PROBE_NAMES = tuple(name for name in CHANNEL_NAMES if not name.startswith("f"))
CHANNEL_GAINS = (0.1, 0.1, 0.1, 0.1, 5e-9, 5e-9, 5e-9, 5e-9)  # unit/count, docs/interfaces.md (channel map)


def _zeros() -> Matrix:
    return ((0.0, 0.0), (0.0, 0.0))


TABLE1_RATIOS = (0.247, 0.363, 0.471, 0.569, 0.677, 0.765, 0.871, 1.041, 1.139, 1.247)  # Omega/omega


@dataclass
class BearingConfig:
    """The four-recess, orifice-compensated hydrostatic journal bearing (sim/bearing.py).

    Geometry of one recess: axial length ``recess_length`` inside the bearing
    length, arc ``recess_angle``, depth ``recess_depth``; ``feed_volume`` the
    oil between the orifice and the recess; ``bulk_modulus`` the effective
    bulk modulus of that oil column with its plumbing (``compressible`` false:
    infinitely stiff, Z nearly constant in Omega). ``fluid_inertia`` adds the
    film's lumped added mass. ``linear`` makes the signals follow the
    linearised bearing exactly (f = -Z d on the orbit) instead of the
    nonlinear film. ``reference_ratios``: the Omega/omega band of truth().
    """

    diameter: float = 0.0381  # m, journal diameter
    length: float = 0.0381  # m, bearing axial length L
    recess_length: float = 0.034  # m, recess axial length l
    recess_angle: float = math.radians(78.0)  # rad, recess arc theta_r
    recess_depth: float = 0.3e-3  # m
    feed_volume: float = 2.0e-6  # m^3 per recess, orifice to recess
    bulk_modulus: float = 5.0e8  # Pa, effective (oil with entrained air and hoses)
    compressible: bool = True
    viscosity: float = 0.098  # Pa s, SAE 30 at 37.8 degC
    density: float = 870.0  # kg/m^3
    fluid_inertia: bool = True
    linear: bool = False
    reference_ratios: tuple[float, ...] = TABLE1_RATIOS


@dataclass
class GeometryConfig:
    """Journal orbit and probe geometry (SI)."""

    clearance: float = 60e-6  # radial clearance c, m
    orbit_ratio: float = 0.04  # eps_d: orbit radius R = eps_d * c
    static_eccentricity: float = 0.0  # eps_s: static offset eps_s * c
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
    strain_gain_error: float = 0.018
    strain_phase_lag: float = math.radians(0.3)


@dataclass
class ChainConfig:
    """Measurement chain of every channel (all off when ``enabled`` is false).

    gain_error: relative gain error per channel (in CHANNEL_NAMES order; for
    a probe channel its sensitivity error on top of
    ``probe_sensitivity_error``, common to all probes). filter_cutoff: corner
    of each channel's (CHANNEL_NAMES order) 2nd-order Butterworth anti-alias filter, Hz (0: none).
    force_delay: the force channels lag the probes by this time, s. probe_delay: each probe's own
    time delay (PROBE_NAMES order: x_a, y_a, x_b, y_b), s; only their differences are measurable."""

    enabled: bool = True
    gain_error: tuple[float, ...] = (0.004, -0.003, 0.002, 0.005, 0.003, -0.002, 0.001, -0.004)
    probe_sensitivity_error: float = -0.01
    filter_cutoff: tuple[float, ...] = (1000.0, 1000.0, 1000.0, 1000.0, 1030.0, 1030.0, 1030.0, 1030.0)
    force_delay: float = 20e-6
    probe_delay: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0)

    def probe_delay_of(self, probe: str) -> float:
        """The own time delay of probe channel `probe` (one of PROBE_NAMES), s."""
        return self.probe_delay[PROBE_NAMES.index(probe)]


@dataclass
class NoiseConfig:
    """Disturbances (all off when ``enabled`` is false). Force levels in N, probe levels in m."""

    enabled: bool = True
    piezo_white: float = 50.0  # N rms per sample
    strain_white: float = 54.0  # N rms
    probe_white: float = 0.09e-6  # m rms
    runout: tuple[float, ...] = (0.225e-6, 0.09e-6)  # m, electrical runout of the probe tracks, spin harmonics 1, 2
    spin_force: tuple[float, ...] = (9.0, 3.6)  # N, spindle unbalance/misalignment at spin harmonics 1, 2
    bearing_orders: tuple[float, ...] = (3.05, 4.95)  # ball-pass orders of the spindle bearings
    bearing_force: float = 3.0  # N per order, force channels
    bearing_probe: float = 3e-9  # m per order, probe channels
    resonance_frequency: float = 143.0  # Hz, structural mode of the bearing housing
    resonance_damping: float = 0.02  # damping ratio
    resonance_force: float = 18.0  # N rms, narrow-band response of that mode
    line_frequency: float = 50.0  # Hz (simulated time)
    line_force: float = 0.4  # N
    line_probe: float = 8e-9  # m
    encoder_jitter: float = math.radians(0.02)  # rad rms slot-edge error
    speed_ripple: float = 3e-4  # relative speed ripple of both spindles
    ripple_frequency: float = 7.7  # Hz (simulated time)


@dataclass
class DrivesConfig:
    """The drives' speed errors: each spindle turns at its reference times 1 + error (fraction),
    off by at most 0.1 % of the speed scale and never beyond MAX_SPEED (a drive's accuracy:
    sim.drive_registers.turning_speed), steadily, and reads that speed back; the two spindles are not phase-locked on the rig (a slow
    roll's spin a fraction ahead of its orbit spindle: docs/calibration.md, the runout step's slip).
    0: each turns exactly at its reference."""

    spin_speed_error: float = 0.0
    orbit_speed_error: float = 0.0


@dataclass
class SupplyConfig:
    """Lubricant supply; recess pressure and beta are the operator's manual settings."""

    recess_pressure: float = 0.4826e6  # Pa, recess pressure of the centred journal at rest
    pressure_ratio: float = 0.25  # beta = p_recess / p_supply
    t_supply: float = 313.15  # K
    heating: float = 1.0e-4  # K per (rad/s)^2 of spin, recess temperature rise


#: the node ids a CANopen node may have (docs/protocols/can-node.md: its frames' ids are base + node id)
CAN_NODE_IDS = range(1, 128)


@dataclass
class CanConfig:
    """The auxiliary sensor node on CAN (sim/can_node.py): its node id, 1 as the contract's node
    (docs/protocols/can-node.md); its frames are the function bases plus it (0x185 ... 0x705 for 5)."""

    node_id: int = 1


#: the fastest simulated time the simulator is asked to keep (simulated s per wall s); its
#: loops cannot follow much faster, and an infinite one stops its clock making sense
MAX_SPEEDUP = 1e4


@dataclass
class SimConfig:
    bearing: BearingConfig = field(default_factory=BearingConfig)
    geometry: GeometryConfig = field(default_factory=GeometryConfig)
    adc: AdcConfig = field(default_factory=AdcConfig)
    lms: LmsConfig = field(default_factory=LmsConfig)
    chain: ChainConfig = field(default_factory=ChainConfig)
    noise: NoiseConfig = field(default_factory=NoiseConfig)
    supply: SupplyConfig = field(default_factory=SupplyConfig)
    drives: DrivesConfig = field(default_factory=DrivesConfig)
    can: CanConfig = field(default_factory=CanConfig)
    speedup: float = 1.0  # simulated time / wall time, > 0 and at most MAX_SPEEDUP
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
    for name in ("spin_speed_error", "orbit_speed_error"):
        if not abs(getattr(cfg.drives, name)) < 0.05:  # within the drives' 5 rpm at-setpoint band at 100 rpm
            p.append(f"drives.{name} must be a fraction within +-0.05, got {getattr(cfg.drives, name)!r}")
    if not (type(cfg.can.node_id) is int and cfg.can.node_id in CAN_NODE_IDS):  # `true` is no node id
        p.append(f"can.node_id must be a CANopen node id 1..127, got {cfg.can.node_id!r}")
    if not 0 < cfg.speedup <= MAX_SPEEDUP:
        p.append(f"speedup must be > 0 and at most {MAX_SPEEDUP:g} (got {cfg.speedup:g})")
    ch = cfg.chain
    if len(ch.gain_error) != len(CHANNEL_NAMES) or len(ch.filter_cutoff) != len(CHANNEL_NAMES):
        p.append(
            f"chain.gain_error and chain.filter_cutoff need {len(CHANNEL_NAMES)} values "
            f"(order {', '.join(CHANNEL_NAMES)})"
        )
    if len(ch.probe_delay) != len(PROBE_NAMES):
        p.append(f"chain.probe_delay needs {len(PROBE_NAMES)} values (order {', '.join(PROBE_NAMES)})")
    if any(f < 0 for f in ch.filter_cutoff):
        p.append("chain.filter_cutoff must be >= 0 Hz (0: no filter)")
    b = cfg.bearing
    positive = dict(
        diameter=b.diameter,
        length=b.length,
        recess_length=b.recess_length,
        recess_angle=b.recess_angle,
        recess_depth=b.recess_depth,
        bulk_modulus=b.bulk_modulus,
        viscosity=b.viscosity,
        density=b.density,
    )
    p += [f"bearing.{name} must be > 0" for name, v in positive.items() if not v > 0]
    if not (b.recess_length < b.length and b.recess_angle < math.pi / 2):
        p.append("bearing: the recesses must leave lands (recess_length < length, recess_angle < 90 deg)")
    if b.feed_volume < 0:
        p.append("bearing.feed_volume must be >= 0")
    if not b.reference_ratios or any(r <= 0 for r in b.reference_ratios):
        p.append("bearing.reference_ratios must be positive Omega/omega values")
    return p
