"""Rig physics: the bearing on the imposed orbit, the probes and the load cells.

Conventions (docs/architecture.md, docs/simulator.md):
- theta = 2 pi s / 360 is the orbit angle after the trigger in time order
  (slot s), whatever the direction. The eccentric (orbit) spindle puts the
  journal at x = X0 + a cos(theta + phi0), y = Y0 + sign(Omega) b sin(theta + phi0)
  (phi0 the trigger phase, (X0, Y0) the static offset): x_bar = a e^{i phi0},
  y_bar = -i sign(Omega) b e^{i phi0}; q = Re(q_bar e^{i theta}).
- The force on the journal is the film force of sim/bearing.py along that
  orbit (its periodic steady state, nonlinear in the orbit radius), or with
  ``bearing.linear`` the linearised f = f0 - Z d; for small orbits its
  fundamental is f_bar = -Z d_bar, Z = K + i|Omega| C - Omega^2 D.
- Every channel then passes its measurement chain (sim/chain.py) and gets its
  disturbances (sim/disturbances.py).
Everything is SI and vectorised over sample arrays; nothing here does I/O.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from sim.bearing import HydrostaticBearing, Supply, bearing_geometry
from sim.chain import channel_chains
from sim.config import SimConfig
from sim.disturbances import Disturbances
from sim.streams import Purpose, SeedStreams

TWO_PI = 2.0 * math.pi
HARMONICS = 12  # harmonics of the orbit kept in the force waveform
GRID = 128  # orbit-angle grid of the periodic film solution
CACHE_SIZE = 1024  # operating points kept by each of the shared caches below

#: film force harmonics and channel harmonics per operating point, shared by every RigPhysics of
#: the same configuration (keyed by its text; the seed plays no part): a Monte Carlo of many
#: seeds over the same points solves each point's film once. Values are read-only arrays.
_FILM: dict[tuple, np.ndarray] = {}
_HARMONICS: dict[tuple, np.ndarray] = {}


def _cached(cache: dict[tuple, np.ndarray], key: tuple, make) -> np.ndarray:
    """cache[key], made by ``make()`` (and frozen) when missing; the cache is emptied when full."""
    value = cache.get(key)
    if value is None:
        value = make()
        value.setflags(write=False)
        if len(cache) >= CACHE_SIZE:
            cache.clear()
        cache[key] = value
    return value


@dataclass(frozen=True)
class ManualSettings:
    """The operator's manual settings (SI)."""

    orbit_radius: float  # m
    static_eccentricity: float  # eps_s, fraction of the clearance
    recess_pressure: float  # Pa
    pressure_ratio: float  # beta = p_recess / p_supply


@dataclass(frozen=True)
class _Channel:
    name: str
    kind: str  # "force" | "probe"
    axis: int  # 0 = x, 1 = y
    lms: str = ""  # piezo | strain
    plane: int = 0  # +1 plane A, -1 plane B


def _channel(name: str) -> _Channel:
    axis = 0 if name[:2] in ("fx", "x_") else 1
    if name.startswith("f"):
        return _Channel(name, "force", axis, lms=name.split("_")[1])
    return _Channel(name, "probe", axis, plane=1 if name.endswith("_a") else -1)


class RigPhysics:
    """The bearing, the orbit and the sensors of the rig (pure numpy)."""

    def __init__(self, cfg: SimConfig):
        self.cfg = cfg
        self.streams = SeedStreams(cfg.seed)  # every random number of this rig (sim/streams.py)
        self.revolutions_drawn = 0  # revolutions sim.revolutions has simulated (keys the next ones' draws)
        g, sup = cfg.geometry, cfg.supply
        self.manual = ManualSettings(
            orbit_radius=g.orbit_ratio * g.clearance,
            static_eccentricity=g.static_eccentricity,
            recess_pressure=sup.recess_pressure,
            pressure_ratio=sup.pressure_ratio,
        )
        self.bearing = HydrostaticBearing(bearing_geometry(cfg.bearing, g.clearance))
        self.channels = [_channel(n) for n in cfg.adc.channels]
        chains = channel_chains(cfg)
        self.chains = [chains[c.name] for c in self.channels]
        white = np.array([self._white_std(c) for c in self.channels])
        phases = self.streams.generator(Purpose.PHASES)
        self.disturbances = Disturbances(cfg.noise, self.channels, white, phases, self.streams)
        self._ripple_phase = phases.uniform(0, TWO_PI)
        # what the deterministic part depends on (the configuration is not changed after construction)
        self._film_key = repr((cfg.bearing, cfg.geometry))
        self._signal_key = repr((cfg.bearing, cfg.geometry, cfg.adc, cfg.chain, cfg.lms))
        self._supply: tuple[ManualSettings, Supply] | None = None
        self.applied_load = np.zeros(2)  # N (x, y): a static calibration load on the journal
        self.reference: tuple[float, float] | None = None  # (N, m): a calibrator on every channel's input
        self.applied_displacement = np.zeros(2)  # m (x, y): a micrometer's static step of the journal

    # ---------------------------------------------------------------- settings
    def set_manual(
        self, *, orbit_radius=None, static_eccentricity=None, recess_pressure=None, pressure_ratio=None
    ) -> None:
        """Change the manual settings (m, -, Pa, -); ValueError when impossible."""
        new = replace(
            self.manual,
            **{
                k: float(v)
                for k, v in dict(
                    orbit_radius=orbit_radius,
                    static_eccentricity=static_eccentricity,
                    recess_pressure=recess_pressure,
                    pressure_ratio=pressure_ratio,
                ).items()
                if v is not None
            },
        )
        c = self.cfg.geometry.clearance
        if new.orbit_radius < 0 or new.static_eccentricity < 0:
            raise ValueError("orbit_radius and static_eccentricity must be >= 0")
        if new.orbit_radius * (1 + abs(self.cfg.geometry.ellipticity)) + new.static_eccentricity * c >= c:
            raise ValueError(
                f"orbit_radius {new.orbit_radius:.3g} m with static_eccentricity "
                f"{new.static_eccentricity:.3g} touches the clearance c = {c:.3g} m"
            )
        if new.recess_pressure < 0:
            raise ValueError("recess_pressure must be >= 0")
        if not 0 < new.pressure_ratio < 1:
            raise ValueError("pressure_ratio must be in (0, 1)")
        self.manual = new

    @property
    def supply(self) -> Supply:
        """Pressures and restrictor of the current manual settings (set at the static position)."""
        m = self.manual
        if self._supply is None or self._supply[0] != m:
            X0, Y0 = self._static()
            self._supply = (m, self.bearing.set_supply(m.recess_pressure, m.pressure_ratio, X0, Y0))
        return self._supply[1]

    # ---------------------------------------------------------------- truth
    def impedances(self, spin: float, orbits) -> np.ndarray:
        """True Z(|Omega|) (n, 2, 2) complex of the bearing linearised at the static
        position, spin omega (rad/s, signed: > 0 turns from +x towards +y; reversing it
        reverses the Couette flow, so the cross-coupled terms change sign), orbit speeds
        Omega (rad/s, sign irrelevant)."""
        X0, Y0 = self._static()
        return self.bearing.impedance(X0, Y0, float(spin), orbits, self.supply)

    def impedance(self, spin: float, orbit: float) -> np.ndarray:
        """True Z (2, 2) complex at spin and orbit (rad/s): f_bar = -Z d_bar."""
        return self.impedances(spin, [orbit])[0]

    def _orbit_axes(self):
        R, e = self.manual.orbit_radius, self.cfg.geometry.ellipticity
        return R * (1 + e), R * (1 - e)

    def _static(self) -> np.ndarray:
        g = self.cfg.geometry
        r = self.manual.static_eccentricity * g.clearance
        return np.array([r * math.cos(g.static_angle), r * math.sin(g.static_angle)])

    def force_harmonics(self, spin: float, orbit: float) -> np.ndarray:
        """Film force on the journal (2, HARMONICS + 1) complex: f = Re sum_h F_h e^{i h psi},
        psi = theta + phi0 the journal's orbit angle in time order (cached per point, read-only)."""
        spin, orbit = float(spin), float(orbit)
        return _cached(_FILM, (self._film_key, spin, orbit, self.manual), lambda: self._solve_force(spin, orbit))

    def _solve_force(self, spin: float, orbit: float) -> np.ndarray:
        s = -1.0 if orbit < 0 else 1.0
        w = abs(orbit)
        a, b = self._orbit_axes()
        X0, Y0 = self._static()
        F = np.zeros((2, HARMONICS + 1), dtype=complex)
        if self.cfg.bearing.linear:
            F[:, 0] = self.bearing.static_force(X0, Y0, spin, self.supply)
            F[:, 1] = -self.impedance(spin, orbit) @ np.array([a, -1j * s * b])
            return F
        psi = TWO_PI * np.arange(GRID) / GRID
        c, sn = np.cos(psi), np.sin(psi)
        f = self.bearing.periodic_force(
            X0 + a * c,
            Y0 + s * b * sn,
            -a * w * sn,
            s * b * w * c,
            -a * w * w * c,
            -s * b * w * w * sn,
            w,
            spin,
            self.supply,
        )
        spec = np.fft.rfft(f, axis=1)[:, : HARMONICS + 1] / GRID
        spec[:, 1:] *= 2.0
        return spec  # f = Re sum_h spec_h e^{i h psi}

    def _probe_harmonics(self, ch: _Channel, orbit: float) -> np.ndarray:
        """(DC, fundamental) of the journal position at probe channel ``ch``, theta referenced."""
        g = self.cfg.geometry
        s = -1.0 if orbit < 0 else 1.0
        E = np.exp(1j * self.cfg.adc.trigger_phase)
        a, b = self._orbit_axes()
        tR = ch.plane * g.probe_tilt * self.manual.orbit_radius
        Et = E * np.exp(1j * s * g.probe_tilt_phase)
        dx, dy = self.applied_displacement
        X = np.array([self._static()[0] + dx, a * E + tR * Et])
        Y = np.array([self._static()[1] + dy, -1j * s * (b * E + tR * Et)])
        half = ch.plane * g.probe_misalignment / 2
        ca, sa = math.cos(half), math.sin(half)
        return ca * X + sa * Y if ch.axis == 0 else -sa * X + ca * Y

    def apply_load(self, fx: float, fy: float) -> None:
        """A known static load (N) on the journal, read by both load measuring systems (0, 0: none)."""
        load = np.array([float(fx), float(fy)])
        if not np.all(np.isfinite(load)):
            raise ValueError("a calibration load must be finite")
        self.applied_load = load

    def apply_displacement(self, dx: float, dy: float) -> None:
        """A known static step (m) of the journal by a micrometer jig: the probes see it, the film
        does not (the probes' calibration; 0, 0: removed)."""
        step = np.array([float(dx), float(dy)])
        if not np.all(np.isfinite(step)):
            raise ValueError("a displacement step must be finite")
        self.applied_displacement = step

    def apply_reference(self, force: float, probe: float) -> None:
        """A calibrator on every channel's input instead of the rig: Re(A e^{i theta}), locked to
        the orbit angle, A = ``force`` N on force channels and ``probe`` m on probe channels; both
        zero: the calibrator is removed. It passes each channel's chain like the real signal."""
        amps = (float(force), float(probe))
        if not all(np.isfinite(amps)):
            raise ValueError("the reference amplitudes must be finite")
        self.reference = None if amps == (0.0, 0.0) else amps

    def channel_harmonics(self, k: int, spin: float, orbit: float) -> np.ndarray:
        """Noise-free signal of channel k after its chain: value = Re sum_h q_h e^{i h theta}
        (a force channel's static part includes the applied calibration load; cached, read-only)."""
        spin, orbit = float(spin), float(orbit)
        state = (self.manual, self.reference, tuple(self.applied_load), tuple(self.applied_displacement))
        key = (self._signal_key, k, spin, orbit, state)
        return _cached(_HARMONICS, key, lambda: self._channel_harmonics(k, spin, orbit))

    def _channel_harmonics(self, k: int, spin: float, orbit: float) -> np.ndarray:
        ch = self.channels[k]
        if self.reference is not None:
            q = np.array([0.0, self.reference[0 if ch.kind == "force" else 1]], dtype=complex)
        elif ch.kind == "force":
            F = self.force_harmonics(spin, orbit)[ch.axis].copy()
            F[0] += self.applied_load[ch.axis]
            q = F * np.exp(1j * np.arange(len(F)) * self.cfg.adc.trigger_phase)
        else:
            q = self._probe_harmonics(ch, orbit)
        f = np.arange(len(q)) * abs(orbit) / TWO_PI
        q = q * self.chains[k].response(f)
        big = np.nonzero(np.abs(q[1:]) > 1e-9 * np.abs(q[1:]).max(initial=0.0))[0]
        return q[: 2 + (big[-1] if big.size else 0)]  # the harmonics that matter, at least DC and 1

    def apparent_impedance(self, spin: float, orbit: float, lms: str = "piezo") -> np.ndarray:
        """The Z (2x2 complex) a perfect identification from the ``lms`` system's forces and the
        probe-plane mean displacements would give: diag(H_fx, H_fy) Z diag(H_x, H_y)^-1, H the
        channels' chain responses at |orbit| (the true Z seen through the calibration errors)."""
        chains = channel_chains(self.cfg)
        f = np.array([abs(float(orbit)) / TWO_PI])

        def h(name: str) -> complex:
            return complex(chains[name].response(f)[0])

        hf = np.array([h(f"fx_{lms}"), h(f"fy_{lms}")])
        hd = np.array([(h("x_a") + h("x_b")) / 2, (h("y_a") + h("y_b")) / 2])
        return hf[:, None] * self.impedance(spin, orbit) / hd[None, :]

    def true_phasors(self, spin: float, orbit: float) -> dict[str, complex]:
        """Noise-free fundamental phasor of every channel (engineering units),
        trigger phase and chain included: what an ideal reader gets, q = Re(q_bar e^{i theta})."""
        return {ch.name: complex(self.channel_harmonics(k, spin, orbit)[1]) for k, ch in enumerate(self.channels)}

    # ---------------------------------------------------------------- signals
    def _white_std(self, ch: _Channel) -> float:
        nz = self.cfg.noise
        if ch.kind == "probe":
            return nz.probe_white
        return nz.piezo_white if ch.lms == "piezo" else nz.strain_white

    def ripple(self, t: np.ndarray) -> np.ndarray:
        """Relative speed ripple factor (1 + r sin(...)) at simulated times t (s)."""
        nz = self.cfg.noise
        if not nz.enabled or nz.speed_ripple == 0:
            return np.ones_like(t)
        return 1.0 + nz.speed_ripple * np.sin(TWO_PI * nz.ripple_frequency * t + self._ripple_phase)

    def channel_values(
        self,
        k: int,
        theta: np.ndarray,
        t: np.ndarray,
        spin_angle: np.ndarray,
        orbit_inst: np.ndarray,
        spin: float,
        orbit: float,
        slots: np.ndarray | None = None,
    ) -> np.ndarray:
        """Engineering values of channel k at the given samples.

        theta: orbit angle after the trigger (rad, time order); t: simulated
        time (s); spin_angle: journal spin angle (rad); orbit_inst: orbit drive
        speed at each sample (rad/s, signed; unused: the film is solved at the
        operating point); spin, orbit: the operating point (rad/s); slots: the global slot index
        of each sample (None: 0, 1, ...), which keys its random draws (sim/streams.py).
        Disturbances are added when the configuration enables them.
        """
        nz = self.cfg.noise
        g = np.arange(np.size(theta)) if slots is None else np.asarray(slots)
        if nz.enabled and nz.encoder_jitter:
            jitter = self.streams.slot_normals(Purpose.JITTER, -1, g)
            jitter *= nz.encoder_jitter
            jitter += theta
            theta = jitter
        q = self.channel_harmonics(k, spin, orbit)
        e = np.empty(np.shape(theta), dtype=complex)  # e^{i theta}, as np.exp gives it, without 1j * theta
        np.cos(theta, out=e.real)
        np.sin(theta, out=e.imag)
        acc = np.full(np.shape(e), q[-1], dtype=complex)
        for qh in q[-2:0:-1]:  # Horner in e^{i theta} down to the fundamental
            acc = acc * e + qh
        val = q[0].real + np.real(acc * e)
        if nz.enabled:
            val = self.disturbances.add(k, val, t, spin_angle, g)
        return np.asarray(val, dtype=float)

    # ---------------------------------------------------------------- supply
    def aux_state(self, spin: float, orbit: float) -> dict:
        """Lubricant and supply conditions at the operating point (SI):
        t_recess, t_groove, t_supply (K), flow (m^3/s), p_supply (Pa),
        p_recess (4,) (Pa), beta, pump_off."""
        sup = self.cfg.supply
        p_s = self.supply.supply_pressure
        X0, Y0 = self._static()
        # the recess the journal sits towards sees a smaller gap, so a higher pressure
        p_rec = self.bearing.equilibrium(X0, Y0, spin, self.supply)
        flow = float(np.sum(self.bearing.flow(X0, Y0, spin, self.supply)))
        rise = sup.heating * spin * spin
        if flow > 0:
            rise *= min(1.0, 1e-4 / flow)  # more flow carries more heat away
        return {
            "t_supply": sup.t_supply,
            "t_recess": sup.t_supply + rise,
            "t_groove": sup.t_supply + 0.6 * rise,
            "flow": flow,
            "p_supply": p_s,
            "p_recess": p_rec,
            "beta": float(np.mean(p_rec) / p_s) if p_s > 0 else 0.0,
            "pump_off": self.manual.recess_pressure <= 0.0,
        }
