"""Rig physics: true bearing coefficients, journal orbit, probe and load-cell signals.

Conventions (docs/architecture.md, docs/orbit-table.md):
- theta = 2 pi s / 360 is the orbit angle after the trigger in time order
  (slot s), whatever the direction. The eccentric (orbit) spindle puts the
  journal at angle psi = sign(Omega) * (theta + phi0) with phi0 the trigger
  phase, so x = a cos(theta + phi0) and y = sign(Omega) * b sin(theta + phi0):
  x_bar = a e^{i phi0}, y_bar = -i sign(Omega) b e^{i phi0}.
- Force on the journal, evaluated in the time domain from first principles:
  f = -(K d + C d' + D d''), velocities from the instantaneous orbit speed,
  plus a second-harmonic nonlinearity and the static load. Its fundamental
  is f_bar = -(K + i|Omega|C - Omega^2 D) d_bar.
- Load measuring system L reads g_L f(theta - lag_L) (gain and phase error).
Everything is SI and vectorised over sample arrays; nothing here does I/O.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from sim.config import SimConfig

TWO_PI = 2.0 * math.pi


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
        self.rng = np.random.default_rng(cfg.seed)
        g, sup = cfg.geometry, cfg.supply
        self.manual = ManualSettings(
            orbit_radius=g.orbit_ratio * g.clearance,
            static_eccentricity=g.static_eccentricity,
            recess_pressure=sup.recess_pressure,
            pressure_ratio=sup.pressure_ratio,
        )
        self._p_ref = sup.recess_pressure * (1.0 - sup.pressure_ratio)
        self.channels = [_channel(n) for n in cfg.adc.channels]
        n = len(self.channels)
        nz = cfg.noise
        # fixed random phases of the deterministic disturbances, per channel
        self._line_phase = self.rng.uniform(0, TWO_PI, n)
        self._bearing_phase = self.rng.uniform(0, TWO_PI, (n, len(nz.bearing_orders)))
        self._runout_phase = self.rng.uniform(0, TWO_PI, (2, len(nz.runout)))  # per plane
        self._ripple_phase = self.rng.uniform(0, TWO_PI)
        self._white = np.array([self._white_std(c) for c in self.channels])

    # ---------------------------------------------------------------- settings
    def set_manual(self, *, orbit_radius=None, static_eccentricity=None,
                   recess_pressure=None, pressure_ratio=None) -> None:
        """Change the manual settings (m, -, Pa, -); ValueError when impossible."""
        new = replace(
            self.manual,
            **{k: float(v) for k, v in dict(
                orbit_radius=orbit_radius, static_eccentricity=static_eccentricity,
                recess_pressure=recess_pressure, pressure_ratio=pressure_ratio,
            ).items() if v is not None},
        )
        c = self.cfg.geometry.clearance
        if new.orbit_radius < 0 or new.static_eccentricity < 0:
            raise ValueError("orbit_radius and static_eccentricity must be >= 0")
        if new.orbit_radius * (1 + abs(self.cfg.geometry.ellipticity)) + new.static_eccentricity * c >= c:
            raise ValueError(
                f"orbit_radius {new.orbit_radius:.3g} m with static_eccentricity "
                f"{new.static_eccentricity:.3g} touches the clearance c = {c:.3g} m")
        if new.recess_pressure < 0:
            raise ValueError("recess_pressure must be >= 0")
        if not 0 < new.pressure_ratio < 1:
            raise ValueError("pressure_ratio must be in (0, 1)")
        self.manual = new

    # ---------------------------------------------------------------- truth
    def coefficients(self, spin: float, orbit: float):
        """True K, C, D (2x2, SI) at spin omega (rad/s) and orbit Omega (rad/s, signed)."""
        b = self.cfg.bearing
        w = abs(float(orbit))
        m, n, p = b.orbit_exponents
        scale = 1.0
        if b.pressure_scaling and self._p_ref > 0:
            scale = self.manual.recess_pressure * (1.0 - self.manual.pressure_ratio) / self._p_ref
        K = np.array(b.K0) * scale + abs(float(spin)) * np.array(b.K_spin) + w**m * np.array(b.K_orbit)
        C = np.array(b.C0) + w**n * np.array(b.C_orbit)
        D = np.array(b.D0) + w**p * np.array(b.D_orbit)
        return K, C, D

    def impedance(self, spin: float, orbit: float) -> np.ndarray:
        """Z = K + i|Omega| C - Omega^2 D (2x2 complex)."""
        K, C, D = self.coefficients(spin, orbit)
        w = abs(float(orbit))
        return K + 1j * w * C - w * w * D

    def _orbit_axes(self):
        R, e = self.manual.orbit_radius, self.cfg.geometry.ellipticity
        return R * (1 + e), R * (1 - e)

    def _static(self) -> np.ndarray:
        g = self.cfg.geometry
        r = self.manual.static_eccentricity * g.clearance
        return np.array([r * math.cos(g.static_angle), r * math.sin(g.static_angle)])

    def _lms(self, lms: str) -> tuple[float, float]:
        L = self.cfg.lms
        if lms == "piezo":
            return 1.0 + L.piezo_gain_error, L.piezo_phase_lag
        return 1.0 + L.strain_gain_error, L.strain_phase_lag

    def true_phasors(self, spin: float, orbit: float) -> dict[str, complex]:
        """Noise-free fundamental phasor of every channel (engineering units),
        trigger phase included: what an ideal reader gets, q = Re(q_bar e^{i theta})."""
        g = self.cfg.geometry
        s = -1.0 if orbit < 0 else 1.0
        E = np.exp(1j * self.cfg.adc.trigger_phase)
        a, b = self._orbit_axes()
        d = np.array([a * E, -1j * s * b * E])
        f = -self.impedance(spin, orbit) @ d
        tR = g.probe_tilt * self.manual.orbit_radius
        Et = E * np.exp(1j * s * g.probe_tilt_phase)
        tau = np.array([tR * Et, -1j * s * tR * Et])
        out = {}
        for ch in self.channels:
            if ch.kind == "force":
                gain, lag = self._lms(ch.lms)
                out[ch.name] = complex(gain * np.exp(-1j * lag) * f[ch.axis])
            else:
                X, Y = d + ch.plane * tau
                ca, sa = math.cos(ch.plane * g.probe_misalignment / 2), math.sin(ch.plane * g.probe_misalignment / 2)
                out[ch.name] = complex(ca * X + sa * Y if ch.axis == 0 else -sa * X + ca * Y)
        return out

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

    def channel_values(self, k: int, theta: np.ndarray, t: np.ndarray, spin_angle: np.ndarray,
                       orbit_inst: np.ndarray, spin: float, orbit: float) -> np.ndarray:
        """Engineering values of channel k at the given samples.

        theta: orbit angle after the trigger (rad, time order); t: simulated
        time (s); spin_angle: journal spin angle (rad); orbit_inst: orbit drive
        speed at each sample (rad/s, signed, before ripple); spin, orbit: the
        operating point for the coefficients (rad/s). Disturbances are added
        when the configuration enables them.
        """
        ch = self.channels[k]
        cfg, nz = self.cfg, self.cfg.noise
        s = -1.0 if orbit < 0 else 1.0
        noisy = nz.enabled
        if noisy and nz.encoder_jitter:
            theta = theta + self.rng.normal(0.0, nz.encoder_jitter, theta.shape)
        a, b = self._orbit_axes()
        q = self._static()
        if ch.kind == "force":
            gain, lag = self._lms(ch.lms)
            psi = s * (theta - lag + cfg.adc.trigger_phase)
            c, sn = np.cos(psi), np.sin(psi)
            w = orbit_inst * self.ripple(t) if noisy else orbit_inst
            K, C, D = self.coefficients(spin, orbit)
            i = ch.axis
            dx, dy = a * c, b * sn
            kn = cfg.bearing.nonlinear * cfg.bearing.K0[0][0] / cfg.geometry.clearance
            nl = kn * (dx * dx - dy * dy) if i == 0 else kn * 2.0 * dx * dy
            val = -(K[i, 0] * dx + K[i, 1] * dy
                    + w * (C[i, 1] * b * c - C[i, 0] * a * sn)
                    - w * w * (D[i, 0] * dx + D[i, 1] * dy)) - nl - (K[i] @ q)
            val = gain * val
            if noisy:
                for o, ph in zip(nz.bearing_orders, self._bearing_phase[k]):
                    val = val + nz.bearing_force * np.sin(o * spin_angle + ph)
                val = val + nz.line_force * np.sin(TWO_PI * nz.line_frequency * t + self._line_phase[k])
        else:
            g = cfg.geometry
            psi = s * (theta + cfg.adc.trigger_phase)
            c, sn = np.cos(psi), np.sin(psi)
            tR = ch.plane * g.probe_tilt * self.manual.orbit_radius
            ct, st = math.cos(g.probe_tilt_phase), math.sin(g.probe_tilt_phase)
            X = q[0] + a * c + tR * (c * ct - sn * st)
            Y = q[1] + b * sn + tR * (sn * ct + c * st)
            half = ch.plane * g.probe_misalignment / 2
            ca, sa = math.cos(half), math.sin(half)
            val = ca * X + sa * Y if ch.axis == 0 else -sa * X + ca * Y
            if noisy:
                plane = 0 if ch.plane > 0 else 1
                shift = 0.0 if ch.axis == 0 else -math.pi / 2  # y probe sits 90 deg on
                for h, (amp, ph) in enumerate(zip(nz.runout, self._runout_phase[plane]), start=1):
                    val = val + amp * np.cos(h * (spin_angle + shift) + ph)
                for o, ph in zip(nz.bearing_orders, self._bearing_phase[k]):
                    val = val + nz.bearing_probe * np.sin(o * spin_angle + ph)
                val = val + nz.line_probe * np.sin(TWO_PI * nz.line_frequency * t + self._line_phase[k])
        if noisy and self._white[k]:
            val = val + self.rng.normal(0.0, self._white[k], np.shape(val))
        return np.asarray(val, dtype=float)

    # ---------------------------------------------------------------- supply
    def aux_state(self, spin: float, orbit: float) -> dict:
        """Lubricant and supply conditions at the operating point (SI):
        t_recess, t_groove, t_supply (K), flow (m^3/s), p_supply (Pa),
        p_recess (4,) (Pa), beta, pump_off."""
        sup, g, m = self.cfg.supply, self.cfg.geometry, self.manual
        p_r, beta = m.recess_pressure, m.pressure_ratio
        p_s = p_r / beta
        pocket = np.radians([0.0, 90.0, 180.0, 270.0])
        # the pocket the journal moves towards sees a smaller gap, so a higher pressure
        dp = 2.0 * (1.0 - beta) * m.static_eccentricity * np.cos(pocket - g.static_angle)
        p_rec = np.clip(p_r * (1.0 + dp), 0.0, p_s)
        area = math.pi * sup.orifice_diameter**2 / 4
        flow = float(np.sum(sup.discharge_coefficient * area
                            * np.sqrt(2.0 * np.maximum(p_s - p_rec, 0.0) / sup.density)))
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
            "pump_off": p_r <= 0.0,
        }
