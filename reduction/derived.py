"""Quantities derived from identified coefficients, with their uncertainty.

At orbit frequencies Omega (rad/s), from K(Omega), C(Omega), D(Omega) (the fitted orders
summed; an absorbed K order lives in D):

- effective damping C_eff,xx = C_xx - K_xy / Omega and C_eff,yy = C_yy + K_yx / Omega (N s/m),
  the usual per-direction form from K and C; its zero crossing Omega_0 is the onset of
  instability. Their mean is Im H_forward / Omega whenever D is symmetric (kc7, kc8, kcd11).
  They leave D out: the damping a forward circular whirl feels in x is
  (Im Z_xx - Re Z_xy) / Omega = C_eff,xx + Omega D_xy (in y: C_eff,yy - Omega D_yx), so with
  D_xy != 0, a skew D (kcd12) or an absorbed K order (it lives in D) the two differ;
- forward and backward direct dynamic stiffness H (N/m): the response of a circular whirl,
  H_f = (Z_xx + Z_yy)/2 + i (Z_yx - Z_xy)/2, H_b = (Z_xx + Z_yy)/2 + i (Z_xy - Z_yx)/2;
- whirl frequency ratio WFR = (K_xy - K_yx) / (omega (C_xx + C_yy)) with omega the journal
  spin (rad/s); for constant isotropic coefficients it equals Omega_0 / omega.

C_eff and H are linear in the coefficients theta, so their variance g^T Sigma g is exact;
the WFR and Omega_0 are linearised (first order). Sigma is the covariance passed in
(statistical by default, or a combined one from :mod:`reduction.systematic`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from reduction.arrays import ComplexArray, FloatArray
from reduction.errors import ReductionError
from reduction.impedance import impedance_basis
from reduction.result import Identification
from rigunits import in_hz

#: a zero crossing of C_eff: (Omega_0 rad/s, its std or None)
Zero = tuple[float, float | None]

_IDX = {"xx": (0, 0), "xy": (0, 1), "yx": (1, 0), "yy": (1, 1)}


@dataclass
class Derived:
    """Derived quantities on the grid ``orbit`` (rad/s); every ``*_std`` is one standard
    deviation (None when the identification has no covariance). Zero crossings are
    (Omega_0 rad/s, std) or None when C_eff does not change sign on the grid."""

    orbit: FloatArray
    c_eff_xx: FloatArray
    c_eff_yy: FloatArray
    c_eff_xx_std: FloatArray | None
    c_eff_yy_std: FloatArray | None
    c_eff_zero_xx: Zero | None
    c_eff_zero_yy: Zero | None
    h_forward: ComplexArray  # N/m
    h_backward: ComplexArray
    h_forward_std: tuple[FloatArray, FloatArray] | None  # (Re, Im)
    h_backward_std: tuple[FloatArray, FloatArray] | None
    wfr: FloatArray
    wfr_std: FloatArray | None

    def to_dict(self) -> dict[str, Any]:
        def arr(a: FloatArray | None) -> list[float] | None:
            return None if a is None else [float(v) for v in np.asarray(a)]

        def pair(p: tuple[FloatArray, FloatArray] | None) -> list[list[float] | None] | None:
            return None if p is None else [arr(p[0]), arr(p[1])]

        return {
            "orbit_hz": arr(in_hz(np.asarray(self.orbit, dtype=float))),
            "c_eff_xx": arr(self.c_eff_xx),
            "c_eff_xx_std": arr(self.c_eff_xx_std),
            "c_eff_yy": arr(self.c_eff_yy),
            "c_eff_yy_std": arr(self.c_eff_yy_std),
            "c_eff_zero_xx_hz": _zero_hz(self.c_eff_zero_xx),
            "c_eff_zero_yy_hz": _zero_hz(self.c_eff_zero_yy),
            "h_forward_re": arr(self.h_forward.real),
            "h_forward_im": arr(self.h_forward.imag),
            "h_forward_std": pair(self.h_forward_std),
            "h_backward_re": arr(self.h_backward.real),
            "h_backward_im": arr(self.h_backward.imag),
            "h_backward_std": pair(self.h_backward_std),
            "wfr": arr(self.wfr),
            "wfr_std": arr(self.wfr_std),
        }


def _zero_hz(z: Zero | None) -> list[float | None] | None:
    if z is None:
        return None
    return [in_hz(z[0]), None if z[1] is None else in_hz(z[1])]


def entry_gradient(ident: Identification, matrix: str, entry: str, orbit: ArrayLike) -> FloatArray:
    """G (n, p) with matrix_entry(Omega_k) = G[k] @ theta, e.g. ("K", "xy"): K_xy(Omega)."""
    w = np.atleast_1d(np.asarray(orbit, dtype=float))
    G = np.zeros((w.size, len(ident.spec.terms)))
    target = _IDX[entry]
    for j, t in enumerate(ident.spec.terms):
        if t.matrix == matrix and target in t.entries:
            G[:, j] = w**t.order
    return G


def _std(G: FloatArray, cov: FloatArray) -> FloatArray:
    """One standard deviation of each row's G[k] @ theta under covariance ``cov``."""
    var: FloatArray = np.einsum("kp,pq,kq->k", G, cov, G)
    return np.sqrt(np.clip(var, 0, None))


def derived_quantities(ident: Identification, orbit: ArrayLike, spin: float, cov: ArrayLike | None = None) -> Derived:
    """C_eff, its zero crossings, H_forward / H_backward and the WFR on ``orbit`` (rad/s, > 0)
    for journal spin ``spin`` (rad/s, > 0 for the WFR); ``cov`` defaults to the fit's."""
    w = np.atleast_1d(np.asarray(orbit, dtype=float))
    if w.size == 0 or np.any(w <= 0) or not np.all(np.isfinite(w)):
        raise ReductionError("derived_quantities: orbit frequencies must be finite and > 0 rad/s")
    sigma = ident.covariance if cov is None else np.asarray(cov, dtype=float)
    theta = ident.theta

    def grad(m: str, e: str) -> FloatArray:
        return entry_gradient(ident, m, e, w)

    g_xx, g_yy = _c_eff(ident, "xx", w), _c_eff(ident, "yy", w)
    E = impedance_basis(ident.spec, w)  # (n, p, 2, 2)
    diag = (E[..., 0, 0] + E[..., 1, 1]) / 2
    skew = (E[..., 1, 0] - E[..., 0, 1]) / 2
    g_hf, g_hb = diag + 1j * skew, diag - 1j * skew
    num = grad("K", "xy") - grad("K", "yx")
    den = grad("C", "xx") + grad("C", "yy")
    n_val, d_val = num @ theta, den @ theta
    with np.errstate(divide="ignore", invalid="ignore"):
        wfr = n_val / (spin * d_val)
        g_wfr = (num * d_val[:, None] - den * n_val[:, None]) / (spin * d_val[:, None] ** 2)
    return Derived(
        orbit=w,
        c_eff_xx=g_xx @ theta,
        c_eff_yy=g_yy @ theta,
        c_eff_xx_std=None if sigma is None else _std(g_xx, sigma),
        c_eff_yy_std=None if sigma is None else _std(g_yy, sigma),
        c_eff_zero_xx=_zero(ident, w, "xx", sigma),
        c_eff_zero_yy=_zero(ident, w, "yy", sigma),
        h_forward=g_hf @ theta,
        h_backward=g_hb @ theta,
        h_forward_std=None if sigma is None else (_std(g_hf.real, sigma), _std(g_hf.imag, sigma)),
        h_backward_std=None if sigma is None else (_std(g_hb.real, sigma), _std(g_hb.imag, sigma)),
        wfr=wfr,
        wfr_std=None if sigma is None or spin <= 0 else _std(g_wfr, sigma),
    )


def _c_eff(ident: Identification, entry: str, orbit: ArrayLike) -> FloatArray:
    w = np.atleast_1d(np.asarray(orbit, dtype=float))
    g: FloatArray
    if entry == "xx":
        g = entry_gradient(ident, "C", "xx", w) - entry_gradient(ident, "K", "xy", w) / w[:, None]
    else:
        g = entry_gradient(ident, "C", "yy", w) + entry_gradient(ident, "K", "yx", w) / w[:, None]
    return g


def _zero(ident: Identification, w: FloatArray, entry: str, cov: FloatArray | None) -> Zero | None:
    """First sign change of C_eff on the grid, refined by bisection; its std by the implicit
    function rule std(C_eff(Omega_0)) / |dC_eff/dOmega|."""
    vals = _c_eff(ident, entry, w) @ ident.theta
    change = np.flatnonzero(np.sign(vals[:-1]) * np.sign(vals[1:]) < 0)
    if change.size == 0:
        return None
    k = int(change[0])

    def f(x: float) -> float:
        return float((_c_eff(ident, entry, x) @ ident.theta)[0])

    from scipy.optimize import brentq  # here: scipy.optimize's import is 0.3 s of every command

    w0 = brentq(f, w[k], w[k + 1], xtol=1e-12 * w[k + 1])
    if cov is None:
        return float(w0), None
    h = 1e-6 * w0
    slope = (f(w0 + h) - f(w0 - h)) / (2 * h)
    g = _c_eff(ident, entry, w0)
    sd = float(_std(g, cov)[0])
    return float(w0), (abs(sd / slope) if slope != 0 else None)
