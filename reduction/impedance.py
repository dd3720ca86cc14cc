"""Impedance equations (paper Eq. 5 to 8) for arbitrary orbits, as a linear regression.

The fluid-film force on the journal is f_bar = -Z(Omega) d_bar with
Z = K + i Omega C - Omega^2 D (Omega in rad/s, each matrix possibly a polynomial in Omega,
see :mod:`reduction.models`). Z is linear in the free coefficients theta:
Z(Omega) = sum_j theta_j E_j(Omega), so every orbit frequency gives the complex pair
f_bar = G theta, i.e. four real equations (Re fx, Im fx, Re fy, Im fy) whatever the orbit's
shape (circular forward or backward, elliptical, ...).
"""

from __future__ import annotations

import numpy as np

from reduction.models import ModelSpec

# Omega-factor of each matrix inside Z
_FACTOR = {"K": lambda w: np.ones_like(w, dtype=complex),
           "C": lambda w: 1j * w,
           "D": lambda w: -(w.astype(complex) ** 2)}


_last_basis: tuple = (None, b"", None)  # (spec, orbit key, E): one identification reuses its basis


def impedance_basis(spec: ModelSpec, orbit) -> np.ndarray:
    """E with Z(Omega_k) = sum_j theta_j E[k, j]: shape (n, p, 2, 2), complex (N/m per unit).

    Read-only; the last (spec, orbit) pair's basis is kept and reused.
    """
    w = np.atleast_1d(np.asarray(orbit, dtype=float))
    key = w.tobytes() + str(w.shape).encode()
    global _last_basis
    last_spec, last_key, last_E = _last_basis  # one read: another thread may replace it
    if last_spec is spec and last_key == key:
        return last_E
    factor = {m: f(w) for m, f in _FACTOR.items()}
    powers = {}
    E = np.zeros(w.shape + (spec.n_coefficients, 2, 2), dtype=complex)
    for j, t in enumerate(spec.terms):
        if t.order not in powers:
            powers[t.order] = w**t.order
        col = factor[t.matrix] * powers[t.order]
        for i, l in t.entries:
            E[..., j, i, l] = col
    E.flags.writeable = False
    _last_basis = (spec, key, E)
    return E


def regressors(spec: ModelSpec, orbit, x, y) -> np.ndarray:
    """G with (fx, fy)_k = G[k] @ theta: shape (n, 2, p), complex, G = -E d (N per unit)."""
    E = impedance_basis(spec, orbit)
    d = np.stack([np.asarray(x, dtype=complex), np.asarray(y, dtype=complex)], axis=-1)
    return -np.einsum("kpil,kl->kip", E, d)


def impedance(spec: ModelSpec, theta, orbit) -> np.ndarray:
    """Z(Omega) for coefficient values theta (column order): shape (n, 2, 2), N/m."""
    return np.einsum("kpil,p->kil", impedance_basis(spec, orbit), np.asarray(theta, dtype=float))


def forces(Z, x, y) -> tuple[np.ndarray, np.ndarray]:
    """f = -Z d: force phasors (N) on the journal from Z (n, 2, 2) and displacements (m)."""
    Z = np.asarray(Z)
    x, y = np.asarray(x, dtype=complex), np.asarray(y, dtype=complex)
    return -(Z[..., 0, 0] * x + Z[..., 0, 1] * y), -(Z[..., 1, 0] * x + Z[..., 1, 1] * y)


def real_rows(G: np.ndarray) -> np.ndarray:
    """Complex (n, 2, ...) -> real (4n, ...) with rows Re fx, Im fx, Re fy, Im fy per frequency."""
    G = np.asarray(G)
    R = np.stack([G.real, G.imag], axis=2)  # (n, 2, 2, ...): [k, force, re/im]
    return R.reshape((4 * G.shape[0],) + G.shape[2:])


def regression(spec: ModelSpec, orbit, x, y, fx, fy) -> tuple[np.ndarray, np.ndarray]:
    """The real regression A theta = b: A (4n, p), b (4n,) in N."""
    A = real_rows(regressors(spec, orbit, x, y))
    b = real_rows(np.stack([np.asarray(fx, dtype=complex), np.asarray(fy, dtype=complex)], axis=-1))
    return A, b
