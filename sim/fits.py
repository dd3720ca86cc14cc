"""Reference best fits of a true impedance Z(Omega) over a list of orbit speeds.

The simulator's truth is Z per orbit frequency. For comparison with an
identification it also offers, by ordinary least squares on the complex
elements of Z (Re and Im equations weighted alike, w = |Omega| rad/s):
- the constant-coefficient model Z = K + i w C - w^2 D;
- the paper's Eq. 15 power model K = K0 + w^m Km, C = C0 + w^n Cn, D = D0 + w^p Dp
  (m, n, p positive integers; with m = 2 or m = p + 2 Km is not fitted, D carries it).
Each element (i, j) is fitted on its own. Pure numpy; SI.
"""

from __future__ import annotations

import numpy as np


def _lstsq(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Least-squares solution for every column of b (n, 4) -> (p, 4)."""
    scale = np.max(np.abs(A), axis=0)
    scale[scale == 0] = 1.0
    x = np.linalg.lstsq(A / scale, b, rcond=None)[0]
    return x / scale[:, None]


def constant_fit(orbits, Z: np.ndarray) -> dict:
    """{"K", "C", "D"} (2x2 each) best fitting Z (n, 2, 2) at orbit speeds (n,) rad/s.

    Re Z = K - w^2 D and Im Z = w C, so K, D come from the real parts and C from
    the imaginary parts. With one frequency D is not separable: D = 0."""
    w = np.abs(np.asarray(orbits, dtype=float))
    re, im = Z.real.reshape(len(w), 4), Z.imag.reshape(len(w), 4)
    if len(np.unique(w)) > 1:
        K, D = _lstsq(np.stack([np.ones_like(w), -w * w], axis=1), re)
    else:
        K, D = re.mean(axis=0), np.zeros(4)
    C = _lstsq(w[:, None], im)[0]
    return {"K": K.reshape(2, 2), "C": C.reshape(2, 2), "D": D.reshape(2, 2)}


def power_fit(orbits, Z: np.ndarray, exponents=(1, 1, 1)) -> dict:
    """Eq. 15 best fit: {"K0", "Km", "C0", "Cn", "D0", "Dp"} (2x2 each), "exponents",
    "absorbed" and "determined".

    The exponents m, n, p are positive integers (the paper's Eq. 15; ValueError otherwise).
    w^m Km has the frequency dependence of -w^2 D0 when m = 2 and of -w^(2+p) Dp when
    m = p + 2: no Z can separate them, so, as the orbit-table contract decides for identify,
    Km is not fitted (zero, ``absorbed`` True) and D carries that term. ``determined`` is
    False when the distinct orbit speeds are fewer than the real equations' columns (K0, D0,
    Dp and Km unless absorbed): the fit is then the minimum-norm one, not the truth."""
    if not all(float(e) == int(e) and e >= 1 for e in exponents) or len(exponents) != 3:
        raise ValueError(f"power_fit: exponents must be three positive integers, got {tuple(exponents)!r}")
    m, n, p = (int(e) for e in exponents)
    w = np.abs(np.asarray(orbits, dtype=float))
    absorbed = m == 2 or m == p + 2
    real_cols = [np.ones_like(w), -w * w, -(w ** (2 + p))] + ([] if absorbed else [w**m])
    re, im = Z.real.reshape(len(w), 4), Z.imag.reshape(len(w), 4)
    K0, D0, Dp, *km = _lstsq(np.stack(real_cols, axis=1), re)
    Km = km[0] if km else np.zeros(4)
    C0, Cn = _lstsq(np.stack([w, w ** (n + 1)], axis=1), im)
    out: dict = {k: v.reshape(2, 2) for k, v in dict(K0=K0, Km=Km, C0=C0, Cn=Cn, D0=D0, Dp=Dp).items()}
    out["exponents"] = (m, n, p)
    out["absorbed"] = absorbed
    out["determined"] = len(np.unique(w)) >= len(real_cols)
    return out
