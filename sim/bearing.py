"""Four-recess, orifice-compensated hydrostatic journal bearing from flow continuity.

Model (docs/simulator.md gives the derivation and its textbook sources):
recess i sits at angle phi_i = 0, 90, 180, 270 deg (unit normal n_i, journal
spin towards +phi). With the journal centre at (X, Y) the film over recess i
is h_i = c - n_i . (X, Y), and at its edges phi_i +/- alpha
h = c - X cos(phi) - Y sin(phi). Per recess, flow continuity:

    (V / B) dp_i/dt = Q_in(p_i) - G(h_i) p_i - Q_couette,i - A_s dh_i/dt

    Q_in = k_o sign(p_s - p) sqrt|p_s - p|          orifice (turbulent restrictor)
    G(h) = B_f h^3 / mu                              Poiseuille flow over the lands
    Q_couette = (U l / 2) (h(phi_i + alpha) - h(phi_i - alpha)),  U = omega D / 2
    V = recess + feed volume, B the effective bulk modulus (infinite when
    compressibility is off: the pressures are then algebraic in h, dh/dt).

The force on the journal is f = -A_e sum_i p_i n_i - M (X'', Y'') (M the
optional fluid inertia, a lumped added mass). The restrictor is set so that
the recesses' mean pressure at rest is p_r with supply p_s = p_r / beta (the
test matrix's two pressure settings). Everything SI; pure numpy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

RECESS_ANGLES = np.radians([0.0, 90.0, 180.0, 270.0])
NORMALS = np.stack([np.cos(RECESS_ANGLES), np.sin(RECESS_ANGLES)], axis=1)  # (4, 2)
# the Couette flow out of recess i is U l sin(alpha) (t_i . d) with t_i = (sin phi_i, -cos phi_i)
TANGENTS = np.stack([np.sin(RECESS_ANGLES), -np.cos(RECESS_ANGLES)], axis=1)
CAVITATION = -0.09e6  # Pa gauge: a recess cannot pull below (the oil releases its air)


@dataclass(frozen=True)
class BearingGeometry:
    """Derived constants of the bearing (SI)."""

    clearance: float  # c, m
    area_eff: float  # A_e, effective projected area per recess, m^2
    area_squeeze: float  # A_s, squeeze area per recess, m^2
    flow_factor: float  # B_f, land flow shape factor (-)
    couette_length: float  # l sin(alpha), m
    radius: float  # journal radius, m
    volume: float  # recess + feed volume per recess, m^3
    bulk_modulus: float  # Pa, inf when incompressible
    viscosity: float  # Pa s
    added_mass: float  # kg, fluid inertia (0 when off)


def bearing_geometry(b, clearance: float) -> BearingGeometry:
    """Derived constants from a BearingConfig ``b`` and the radial clearance (m).

    Lands: axial land width l_a = (L - l)/2 on both ends of a recess of axial
    length l and arc length s = R theta_r; circumferential lands of width
    l_c = R (pi/2 - theta_r)/2 to the drain grooves between recesses. Flow
    shape factor B_f = (2 s / l_a + 2 l / l_c) / 12 (corners neglected).
    Effective area: recess plus half of each land, projected on n_i:
    A_e = (l + l_a) 2 R sin(theta_e / 2), theta_e = theta_r + l_c / R.
    """
    R = b.diameter / 2
    l, L, th = b.recess_length, b.length, b.recess_angle
    l_a = (L - l) / 2
    l_c = R * (math.pi / 2 - th) / 2
    if l_a <= 0 or l_c <= 0:
        raise ValueError("bearing: recesses leave no lands (recess_length < length, recess_angle < 90 deg)")
    s = R * th
    th_e = th + l_c / R
    area_eff = (l + l_a) * 2 * R * math.sin(th_e / 2)
    volume = s * l * b.recess_depth + b.feed_volume
    mass = math.pi * b.density * R * L**3 / (12 * clearance) if b.fluid_inertia else 0.0
    return BearingGeometry(
        clearance=clearance,
        area_eff=area_eff,
        area_squeeze=area_eff,
        flow_factor=(2 * s / l_a + 2 * l / l_c) / 12,
        couette_length=l * math.sin(th / 2),
        radius=R,
        volume=volume,
        bulk_modulus=b.bulk_modulus if b.compressible else math.inf,
        viscosity=b.viscosity,
        added_mass=mass,
    )


@dataclass(frozen=True)
class Supply:
    """Pressure settings: recess pressure p_r (Pa), ratio beta, so p_s = p_r / beta, and
    the orifice constant k_o (m^3/s/sqrt(Pa)) the operator's restrictor setting gives."""

    recess_pressure: float
    pressure_ratio: float
    orifice: float

    @property
    def supply_pressure(self) -> float:
        return self.recess_pressure / self.pressure_ratio


class HydrostaticBearing:
    """Film forces of the bearing: quasi-static, periodic (nonlinear) and linearised."""

    def __init__(self, geometry: BearingGeometry):
        self.g = geometry

    # ---------------------------------------------------------------- flows
    def land_conductance(self, h):
        """G(h) = B_f h^3 / mu, m^3/(s Pa)."""
        g = self.g
        return g.flow_factor * np.asarray(h) ** 3 / g.viscosity

    def set_supply(self, recess_pressure: float, pressure_ratio: float, X0: float = 0.0, Y0: float = 0.0) -> Supply:
        """The operator's setting: supply p_s = p_r / beta, restrictor adjusted until the
        recesses' mean pressure reads p_r with the journal at rest at (X0, Y0). Centred,
        k_o = G(c) p_r / sqrt(p_s - p_r) in closed form; off centre by bisection on k_o."""
        p_r, beta = recess_pressure, pressure_ratio
        if p_r <= 0:
            return Supply(p_r, beta, 0.0)
        p_s = p_r / beta
        k_c = float(self.land_conductance(self.g.clearance)) * p_r / math.sqrt(p_s - p_r)
        if X0 == 0.0 and Y0 == 0.0:
            return Supply(p_r, beta, k_c)
        h, _ = self.films(X0, Y0)
        lo, hi = math.log(k_c) - 7.0, math.log(k_c) + 7.0
        for _ in range(60):  # mean pressure grows with k_o
            mid = 0.5 * (lo + hi)
            mean = float(np.mean(self.quasi_static_pressures(h, 0.0, math.exp(mid), p_s)))
            lo, hi = (mid, hi) if mean < p_r else (lo, mid)
        return Supply(p_r, beta, math.exp(0.5 * (lo + hi)))

    def films(self, X, Y):
        """(h at the recess centres, Couette outflow per unit surface speed), shape (4, ...)."""
        X, Y = np.asarray(X, dtype=float), np.asarray(Y, dtype=float)
        outer = np.multiply.outer
        h = self.g.clearance - outer(NORMALS[:, 0], X) - outer(NORMALS[:, 1], Y)
        cq = self.g.couette_length * (outer(TANGENTS[:, 0], X) + outer(TANGENTS[:, 1], Y))
        return h, cq

    def quasi_static_pressures(self, h, outflow, k_o: float, p_s: float):
        """Recess pressures when V/B = 0: k_o sgn(p_s-p) sqrt|p_s-p| = G(h) p + outflow.

        Closed form in u = sgn(p_s - p) sqrt|p_s - p|: G u|u| + k_o u = G p_s + outflow."""
        G = self.land_conductance(np.maximum(h, 1e-3 * self.g.clearance))
        rhs = G * p_s + outflow
        if k_o == 0.0:
            return np.zeros_like(rhs)
        u = 2 * rhs / (k_o + np.sqrt(k_o * k_o + 4 * G * np.abs(rhs)))
        return p_s - np.sign(u) * u * u

    # ---------------------------------------------------------------- static
    def equilibrium(self, X0: float, Y0: float, spin: float, supply: Supply) -> np.ndarray:
        """Recess pressures (4,) with the journal held at (X0, Y0), spinning at omega (rad/s)."""
        h, cq = self.films(X0, Y0)
        U = spin * self.g.radius
        return self.quasi_static_pressures(h, U * cq, supply.orifice, supply.supply_pressure)

    def static_force(self, X0: float, Y0: float, spin: float, supply: Supply) -> np.ndarray:
        """Film force on the journal (2,) held at (X0, Y0), N."""
        p = np.maximum(self.equilibrium(X0, Y0, spin, supply), CAVITATION)
        return -self.g.area_eff * NORMALS.T @ p

    # ---------------------------------------------------------------- linear
    def impedance(self, X0: float, Y0: float, spin: float, orbit, supply: Supply) -> np.ndarray:
        """Z(|Omega|) (n, 2, 2) complex of the bearing linearised about (X0, Y0).

        delta p_i = [(3 G p_i / h_i + i w A_s) n_i - U l sin(alpha) t_i] . delta d
                    / (g_o,i + G_i + i w V / B),   g_o = k_o / (2 sqrt(p_s - p_i)),
        f = -Z d with Z = A_e sum_i n_i a_i^T - w^2 M (w = |Omega|)."""
        g = self.g
        w = np.abs(np.atleast_1d(np.asarray(orbit, dtype=float)))[:, None]  # (n, 1)
        p = self.equilibrium(X0, Y0, spin, supply)
        h, _ = self.films(X0, Y0)
        G = self.land_conductance(h)
        k_o, p_s = supply.orifice, supply.supply_pressure
        g_o = k_o / (2 * np.sqrt(np.maximum(np.abs(p_s - p), 1e-9 * p_s))) if k_o > 0 else np.zeros(4)
        cap = 0.0 if math.isinf(g.bulk_modulus) else g.volume / g.bulk_modulus
        den = g_o + G + 1j * w * cap  # (n, 4)
        normal = (3 * G * p / h + 1j * w * g.area_squeeze) / den  # (n, 4) times n_i
        tangent = -(spin * g.radius * g.couette_length) / den  # (n, 4) times t_i
        a = normal[:, :, None] * NORMALS + tangent[:, :, None] * TANGENTS  # (n, 4, 2)
        Z = g.area_eff * np.einsum("ik,nil->nkl", NORMALS, a)
        return Z - (w * w * g.added_mass)[:, :, None] * np.eye(2)

    # ---------------------------------------------------------------- periodic
    def periodic_pressures(
        self, X, Y, Xd, Yd, w: float, spin: float, supply: Supply, tol: float = 1e-10, max_iter: int = 200
    ) -> np.ndarray:
        """Steady periodic recess pressures (4, N) along one orbit period.

        X, Y (N,) journal centre on a uniform grid of the orbit angle in time
        order, Xd, Yd (N,) its velocity (m/s), w = |Omega| (rad/s). With
        compressibility the continuity ODE is solved by a chord iteration in
        the Fourier domain: (i k w V/B + g0) P_k = FFT(r(p) + g0 p)_k, with r the
        flow surplus and g0 the recess's mean conductance (converges while the
        conductance varies by less than g0 along the orbit)."""
        g = self.g
        h, cq = self.films(X, Y)
        hd = -(NORMALS[:, 0:1] * Xd + NORMALS[:, 1:2] * Yd)
        out = spin * g.radius * cq + g.area_squeeze * hd
        k_o, p_s = supply.orifice, supply.supply_pressure
        p = self.quasi_static_pressures(h, out, k_o, p_s)
        if math.isinf(g.bulk_modulus) or w == 0.0 or k_o == 0.0:
            return p
        cap = g.volume / g.bulk_modulus
        n = p.shape[1]
        k = np.fft.rfftfreq(n, 1.0 / n)
        G = self.land_conductance(np.maximum(h, 1e-3 * g.clearance))
        for _ in range(max_iter):
            gap = p_s - p
            q_in = k_o * np.sign(gap) * np.sqrt(np.abs(gap))
            g_o = k_o / (2 * np.sqrt(np.maximum(np.abs(gap), 1e-6 * p_s)))
            g0 = np.mean(g_o + G, axis=1, keepdims=True)
            rhs = np.fft.rfft(q_in - G * p - out + g0 * p, axis=1)
            new = np.fft.irfft(rhs / (1j * k * w * cap + g0), n=n, axis=1)
            step = np.max(np.abs(new - p))
            p = new
            if step < tol * p_s:
                break
        return p

    def periodic_force(self, X, Y, Xd, Yd, Xdd, Ydd, w: float, spin: float, supply: Supply) -> np.ndarray:
        """Film force on the journal (2, N) along the orbit (see periodic_pressures), N."""
        p = np.maximum(self.periodic_pressures(X, Y, Xd, Yd, w, spin, supply), CAVITATION)
        f = -self.g.area_eff * NORMALS.T @ p
        return f - self.g.added_mass * np.stack([Xdd, Ydd])

    def flow(self, X0: float, Y0: float, spin: float, supply: Supply) -> np.ndarray:
        """Supply flow into each recess (4,) at the static position, m^3/s."""
        p = self.equilibrium(X0, Y0, spin, supply)
        gap = supply.supply_pressure - p
        return supply.orifice * np.sign(gap) * np.sqrt(np.abs(gap))
