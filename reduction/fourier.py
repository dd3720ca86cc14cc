"""Fourier decomposition of angle-sampled (time-averaged) signals at known orbit angles.

Convention: q(theta) = mean + Re(q_bar e^{i h theta}) = mean + a cos(h theta) - b sin(h theta)
with q_bar = a + i b, theta the orbit angle after the trigger in rad, h the harmonic. The
complex amplitude q_bar is fitted by least squares at the samples' own angles, so samples at
arbitrary angles (a multiplexed channel sampled at slots k, k+8, ... of the 360-slot disk,
theta = 2 pi slot / 360) need no separate phase correction. For uniform full-circle angles the
fit reduces to q_bar = (2/N) sum_s q_s e^{-i h theta_s}.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from reduction.errors import ReductionError


class HarmonicFit(NamedTuple):
    """Least-squares fit of mean + Re(phasor e^{i h theta}); ``rms_residual`` is the RMS of the
    samples minus that fit (same unit as the samples)."""

    mean: np.ndarray
    phasor: np.ndarray
    rms_residual: np.ndarray


def _aligned(samples: ArrayLike, theta: ArrayLike, axis: int) -> tuple[np.ndarray, np.ndarray]:
    q = np.asarray(samples, dtype=float)
    th = np.asarray(theta, dtype=float)
    if q.ndim == 0:
        raise ReductionError("samples must have at least one axis")
    axis = axis % q.ndim
    if th.ndim == 1 and q.ndim > 1:  # angles along the sample axis only
        if th.shape[0] != q.shape[axis]:
            raise ReductionError(f"theta has {th.shape[0]} angles, samples have {q.shape[axis]} along axis {axis}")
        th = th.reshape([-1 if i == axis else 1 for i in range(q.ndim)])
    try:
        np.broadcast_shapes(q.shape, th.shape)
    except ValueError as err:
        raise ReductionError(f"theta of shape {th.shape} does not broadcast with samples {q.shape}") from err
    if th.ndim > q.ndim or (th.ndim == q.ndim and th.shape[axis] != q.shape[axis]):
        raise ReductionError("theta must give one angle per sample along axis")
    th = th.reshape((1,) * (q.ndim - th.ndim) + th.shape)
    if q.shape[axis] == 0:
        raise ReductionError(f"no samples along axis {axis}")
    if not np.all(np.isfinite(th)):
        raise ReductionError("theta contains a non-finite angle (NaN or inf)")
    if not np.all(np.isfinite(q)):
        raise ReductionError("samples contain a non-finite value (NaN or inf)")
    return np.moveaxis(q, axis, -1), np.moveaxis(th, axis, -1)


def harmonic_fit(samples: ArrayLike, theta: ArrayLike, harmonic: int = 1, axis: int = -1) -> HarmonicFit:
    """Fit mean + Re(q_bar e^{i h theta}) to ``samples`` taken at angles ``theta`` (rad).

    ``theta`` broadcasts against ``samples`` (e.g. one angle row per channel, shared by
    every record) or is 1-D along ``axis``. Vectorised over all other axes. Raises
    ReductionError when the angles cannot separate the harmonic (fewer than 3 distinct
    phases of h theta), when there are no samples, or when a sample or angle is NaN or inf.
    """
    if int(harmonic) != harmonic or harmonic < 1:
        raise ReductionError(f"harmonic must be a positive integer, got {harmonic!r}")
    q, th = _aligned(samples, theta, axis)
    c, s = np.cos(harmonic * th), np.sin(harmonic * th)
    one = np.ones_like(c)
    # normal equations of the basis (1, cos, -sin), batched 3x3 (angles only: cheap when shared)
    basis = (one, c, -s)
    N = np.stack([np.stack([np.sum(u * v, axis=-1) for v in basis], axis=-1) for u in basis], axis=-2)
    rhs = np.stack([np.sum(q * u, axis=-1) for u in basis], axis=-1)
    scale = np.sum(one, axis=-1)[..., None, None]
    det = np.linalg.det(N / scale)
    if np.any(np.abs(det) < 1e-10):
        raise ReductionError(f"the sample angles cannot resolve harmonic {harmonic} (need at least 3 distinct phases)")
    batch = np.broadcast_shapes(N.shape[:-2], rhs.shape[:-1])
    N, rhs = np.broadcast_to(N, batch + (3, 3)), np.broadcast_to(rhs, batch + (3,))
    coef = np.linalg.solve(N, rhs[..., None])[..., 0]
    mean, a, b = coef[..., 0], coef[..., 1], coef[..., 2]
    model = mean[..., None] + a[..., None] * c - b[..., None] * s
    rms = np.sqrt(np.mean((q - model) ** 2, axis=-1))
    return HarmonicFit(mean, a + 1j * b, rms)


def phasor(samples: ArrayLike, theta: ArrayLike, harmonic: int = 1, axis: int = -1) -> np.ndarray:
    """Complex amplitude q_bar of harmonic h at arbitrary known angles (least squares);
    q(theta) = mean + Re(q_bar e^{i h theta}). See :func:`harmonic_fit`."""
    return harmonic_fit(samples, theta, harmonic, axis).phasor


def phasor_weights(theta: ArrayLike) -> np.ndarray:
    """(P, S) complex weights w with q_bar = sum_s w[p, s] q[p, s]: the least-squares fundamental
    of :func:`phasor` (linear in the samples) at each row's angles theta (P, S, rad)."""
    angles = np.asarray(theta, dtype=float)
    p, s = angles.shape
    return phasor(np.broadcast_to(np.eye(s), (p, s, s)), angles[:, None, :])
