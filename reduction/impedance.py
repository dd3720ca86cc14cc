"""Impedance equations (paper Eq. 5 to 8) for arbitrary orbits, as a linear regression.

The fluid-film force on the journal is f_bar = -Z(Omega) d_bar with
Z = K + i Omega C - Omega^2 D (Omega in rad/s, each matrix possibly a polynomial in Omega,
see :mod:`reduction.models`). Z is linear in the free coefficients theta:
Z(Omega) = sum_j theta_j E_j(Omega), so every orbit frequency gives the complex pair
f_bar = G theta, i.e. four real equations (Re fx, Im fx, Re fy, Im fy) whatever the orbit's
shape (circular forward or backward, elliptical, ...).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike

from reduction.arrays import ComplexArray, FloatArray
from reduction.models import ModelSpec

# Omega-factor of each matrix inside Z
_FACTOR: dict[str, Callable[[FloatArray], ComplexArray]] = {
    "K": lambda w: np.ones_like(w, dtype=complex),
    "C": lambda w: np.asarray(1j * w, dtype=complex),
    "D": lambda w: -(w.astype(complex) ** 2),
}


_last_basis: tuple[ModelSpec | None, bytes, ComplexArray | None] = (
    None,
    b"",
    None,
)  # (spec, orbit key, E): one identification reuses its basis


def impedance_basis(spec: ModelSpec, orbit: ArrayLike) -> ComplexArray:
    """E with Z(Omega_k) = sum_j theta_j E[k, j]: shape (n, p, 2, 2), complex (N/m per unit).

    Read-only; the last (spec, orbit) pair's basis is kept and reused.
    """
    w = np.atleast_1d(np.asarray(orbit, dtype=float))
    key = w.tobytes() + str(w.shape).encode()
    global _last_basis
    last_spec, last_key, last_E = _last_basis  # one read: another thread may replace it
    if last_spec is spec and last_key == key and last_E is not None:
        return last_E
    factor = {m: f(w) for m, f in _FACTOR.items()}
    powers: dict[int, FloatArray] = {}
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


_PHASE = {"K": (1.0, 0), "C": (1j, 1), "D": (-1.0, 2)}
IMPEDANCE_ROWS = 65536  # orbit frequencies per block: the (rows, p) complex Omega factors stay small  # Omega-factor of each matrix: phase x Omega^k


def impedance_columns(spec: ModelSpec, w: FloatArray) -> ComplexArray:
    """(n, p) complex: each free coefficient's Omega factor (1, i Omega or -Omega^2, times
    Omega^r) - the one nonzero value its basis matrix holds at its entries."""
    powers: dict[int, FloatArray] = {}
    out = np.empty(w.shape + (spec.n_coefficients,), dtype=complex)
    for j, t in enumerate(spec.terms):
        phase, k = _PHASE[t.matrix]
        r = t.order + k
        if r not in powers:
            powers[r] = w**r if r else np.ones_like(w)
        out[..., j] = phase * powers[r]
    return out


def regressors(spec: ModelSpec, orbit: ArrayLike, x: ArrayLike, y: ArrayLike) -> ComplexArray:
    """G with (fx, fy)_k = G[k] @ theta: shape (n, 2, p), complex, G = -E d (N per unit)."""
    w = np.atleast_1d(np.asarray(orbit, dtype=float))
    d = np.stack([np.asarray(x, dtype=complex), np.asarray(y, dtype=complex)], axis=-1)
    cols = impedance_columns(spec, w)
    G = np.zeros(w.shape + (2, spec.n_coefficients), dtype=complex)
    for j, t in enumerate(spec.terms):
        for i, l in t.entries:
            G[:, i, j] -= cols[:, j] * d[:, l]
    return G


def regression_rows(spec: ModelSpec, orbit: ArrayLike, x: ArrayLike, y: ArrayLike) -> FloatArray:
    """real_rows(regressors(...)) filled column by column: (4n, p) real, no (n, 2, p)
    complex intermediate (rows Re fx, Im fx, Re fy, Im fy per orbit frequency)."""
    w = np.atleast_1d(np.asarray(orbit, dtype=float))
    d = (np.asarray(x, dtype=complex), np.asarray(y, dtype=complex))
    A = np.zeros((4 * w.shape[0], spec.n_coefficients), order="F")  # columns contiguous while filled
    for s in range(0, w.shape[0], IMPEDANCE_ROWS):  # the Omega factors of one block of rows at a time
        e = min(s + IMPEDANCE_ROWS, w.shape[0])
        cols = impedance_columns(spec, w[s:e])
        for j, t in enumerate(spec.terms):
            column = A[4 * s : 4 * e, j]
            for i, l in t.entries:
                g = cols[:, j] * d[l][s:e]
                column[2 * i :: 4] -= g.real
                column[2 * i + 1 :: 4] -= g.imag
    return A


def impedance(spec: ModelSpec, theta: ArrayLike, orbit: ArrayLike) -> ComplexArray:
    """Z(Omega) for coefficient values theta (column order): shape (n, 2, 2), N/m."""
    w = np.atleast_1d(np.asarray(orbit, dtype=float))
    coefficients = np.asarray(theta, dtype=float).astype(complex)
    Z = np.zeros(w.shape + (2, 2), dtype=complex)
    filling = _filling(spec).items()
    for s in range(0, max(w.shape[0], 1), IMPEDANCE_ROWS):
        cols = impedance_columns(spec, w[s : s + IMPEDANCE_ROWS])
        for (i, l), J in filling:
            Z[s : s + IMPEDANCE_ROWS, i, l] = cols[:, J] @ coefficients[J]
    return Z


def _filling(spec: ModelSpec) -> dict[tuple[int, int], list[int]]:
    """Z's entry (i, l) -> the free coefficients whose basis fills it."""
    out: dict[tuple[int, int], list[int]] = {}
    for j, t in enumerate(spec.terms):
        for i, l in t.entries:
            out.setdefault((i, l), []).append(j)
    return out


def forces(Z: ArrayLike, x: ArrayLike, y: ArrayLike) -> tuple[ComplexArray, ComplexArray]:
    """f = -Z d: force phasors (N) on the journal from Z (n, 2, 2) and displacements (m)."""
    z = np.asarray(Z, dtype=complex)
    xc, yc = np.asarray(x, dtype=complex), np.asarray(y, dtype=complex)
    return -(z[..., 0, 0] * xc + z[..., 0, 1] * yc), -(z[..., 1, 0] * xc + z[..., 1, 1] * yc)


def real_rows(G: ArrayLike) -> FloatArray:
    """Complex (n, 2, ...) -> real (4n, ...) with rows Re fx, Im fx, Re fy, Im fy per frequency."""
    g = np.asarray(G)
    R = np.stack([g.real, g.imag], axis=2)  # (n, 2, 2, ...): [k, force, re/im]
    return R.reshape((4 * g.shape[0],) + g.shape[2:])


def regression(
    spec: ModelSpec, orbit: ArrayLike, x: ArrayLike, y: ArrayLike, fx: ArrayLike, fy: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """The real regression A theta = b: A (4n, p), b (4n,) in N."""
    A = regression_rows(spec, orbit, x, y)
    b = real_rows(np.stack([np.asarray(fx, dtype=complex), np.asarray(fy, dtype=complex)], axis=-1))
    return A, b


def real_operator(W: ArrayLike) -> FloatArray:
    """Complex (n, 2, 2) row operators -> real (n, 4, 4) acting on each row's four real_rows entries
    (Re, Im of the first component, then of the second): real_rows(W_k r_k) = out[k] @ real_rows(r_k)."""
    w = np.asarray(W, dtype=complex)
    units = np.array([[1, 0], [1j, 0], [0, 1], [0, 1j]])  # the inputs Re r_1, Im r_1, Re r_2, Im r_2
    image = np.einsum("kij,uj->kui", w, units)  # (n, 4 inputs, 2 outputs)
    out: FloatArray = np.stack([image.real, image.imag], axis=3).reshape(w.shape[0], 4, 4).transpose(0, 2, 1)
    return out
