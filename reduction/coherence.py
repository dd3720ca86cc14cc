"""Coherence of input motion and output force at each orbit frequency (paper Eq. 17, 18).

From n_d records (e.g. revolutions) with per-record phasors X_s, F_s at the orbit
frequency: G_xf = mean_s conj(X_s) F_s, G_xx = mean_s |X_s|^2, G_ff = mean_s |F_s|^2 and
gamma^2 = |G_xf|^2 / (G_xx G_ff) in [0, 1] (the paper's factor 2 / (2 pi n_d) cancels).
"""

from __future__ import annotations

import numpy as np

from reduction.errors import ReductionError


def coherence(x_records, f_records, axis: int = 0) -> np.ndarray:
    """gamma^2 of input phasors ``x_records`` and output phasors ``f_records`` (complex,
    broadcast together) over the records along ``axis``. NaN where either power is zero."""
    X = np.asarray(x_records, dtype=complex)
    F = np.asarray(f_records, dtype=complex)
    try:
        X, F = np.broadcast_arrays(X, F)
    except ValueError as err:
        raise ReductionError(f"coherence: record shapes {X.shape} and {F.shape} do not broadcast") from err
    if X.ndim == 0 or X.shape[axis] < 1:
        raise ReductionError("coherence needs at least one record along axis")
    gxf = np.mean(np.conj(X) * F, axis=axis)
    gxx = np.mean(np.abs(X) ** 2, axis=axis)
    gff = np.mean(np.abs(F) ** 2, axis=axis)
    den = gxx * gff
    with np.errstate(invalid="ignore", divide="ignore"):
        g = np.where(den > 0, np.abs(gxf) ** 2 / np.where(den > 0, den, 1.0), np.nan)
    return np.clip(g, 0.0, 1.0)


def orbit_coherences(x, y, fx, fy, axis: int = 0) -> np.ndarray:
    """The four coherences of an orbit table row, last axis ordered xfx, yfx, xfy, yfy
    (the table's gamma2 columns), from per-record phasors with records along ``axis``."""
    return np.stack([coherence(x, fx, axis), coherence(y, fx, axis),
                     coherence(x, fy, axis), coherence(y, fy, axis)], axis=-1)


def coherence_weights(gamma2, fx, fy, floor: float = 1e-9) -> np.ndarray:
    """Weighted-least-squares weights (inverse variances) of the 4n real equations.

    The usual frequency-response variance: a force phasor of coherence gamma^2 with the
    motion has relative variance (1 - gamma^2) / gamma^2 (output noise power over coherent
    power, per record), so var(f) ~ |f|^2 (1 - gamma^2) / gamma^2 on both Re and Im. For fx
    gamma^2 is the mean of gamma2_xfx and gamma2_yfx (x and y are coherent with each other
    on a single-frequency orbit, so each ordinary coherence is the multiple coherence),
    likewise for fy. (1 - gamma^2) / gamma^2 is floored at ``floor`` so that gamma^2 = 1
    gives a large finite weight. Returns (4n,) weights, rows Re fx, Im fx, Re fy, Im fy.
    """
    g = np.asarray(gamma2, dtype=float)
    fx, fy = np.asarray(fx, dtype=complex), np.asarray(fy, dtype=complex)
    gx = np.clip((g[:, 0] + g[:, 1]) / 2, 1e-12, 1.0)
    gy = np.clip((g[:, 2] + g[:, 3]) / 2, 1e-12, 1.0)
    mag2 = np.stack([np.abs(fx) ** 2, np.abs(fy) ** 2], axis=1)
    mag2 = np.maximum(mag2, 1e-12 * max(float(np.mean(mag2)), np.finfo(float).tiny))
    rel = np.maximum(np.stack([(1 - gx) / gx, (1 - gy) / gy], axis=1), floor)
    var = mag2 * rel  # (n, 2)
    return np.repeat(1.0 / var, 2, axis=1).reshape(-1)
