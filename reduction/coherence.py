"""Coherence of input motion and output force at each orbit frequency (paper Eq. 17, 18).

From n_d records (e.g. revolutions) with per-record phasors X_s, F_s at the orbit
frequency: G_xf = mean_s conj(X_s) F_s, G_xx = mean_s |X_s|^2, G_ff = mean_s |F_s|^2 and
gamma^2 = |G_xf|^2 / (G_xx G_ff) in [0, 1] (the paper's factor 2 / (2 pi n_d) cancels).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from reduction.errors import ReductionError


def coherence(x_records: ArrayLike, f_records: ArrayLike, axis: int = 0) -> np.ndarray:
    """gamma^2 of input phasors ``x_records`` and output phasors ``f_records`` (complex,
    broadcast together) over the records along ``axis``. NaN where either power is zero;
    ReductionError for a non-finite record."""
    X = np.asarray(x_records, dtype=complex)
    F = np.asarray(f_records, dtype=complex)
    try:
        X, F = np.broadcast_arrays(X, F)
    except ValueError as err:
        raise ReductionError(f"coherence: record shapes {X.shape} and {F.shape} do not broadcast") from err
    if X.ndim == 0 or X.shape[axis] < 1:
        raise ReductionError("coherence needs at least one record along axis")
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(F))):
        raise ReductionError("coherence: a record phasor is not finite (NaN or inf)")
    gxf = np.mean(np.conj(X) * F, axis=axis)
    gxx = np.mean(np.abs(X) ** 2, axis=axis)
    gff = np.mean(np.abs(F) ** 2, axis=axis)
    den = gxx * gff
    with np.errstate(invalid="ignore", divide="ignore"):
        g = np.where(den > 0, np.abs(gxf) ** 2 / np.where(den > 0, den, 1.0), np.nan)
    return np.clip(g, 0.0, 1.0)


def orbit_coherences(x: ArrayLike, y: ArrayLike, fx: ArrayLike, fy: ArrayLike, axis: int = 0) -> np.ndarray:
    """The four coherences of an orbit table row, last axis ordered xfx, yfx, xfy, yfy
    (the table's gamma2 columns), from per-record phasors with records along ``axis``."""
    return np.stack(
        [coherence(x, fx, axis), coherence(y, fx, axis), coherence(x, fy, axis), coherence(y, fy, axis)], axis=-1
    )
