"""Noise of the averaged phasors: per-row uncertainties and the regression's weights.

An orbit table row holds phasors averaged over n revolutions (records). Their standard
uncertainty u = sqrt(E|error|^2) of the complex value (m or N) is estimated from the scatter
of the per-revolution phasors, :func:`phasor_uncertainty`. For circular complex noise each
of Re and Im carries the variance u^2 / 2.

In the regression f = -Z d the residual of one force equation carries the force noise and,
through Z, the displacement noise: var(r_x) = u_fx^2 + |Z_xx|^2 u_x^2 + |Z_xy|^2 u_y^2
(likewise r_y), :func:`equation_variances` - the effective variance that gives the weights
of ``wls``, the covariance and the chi2 when the table has u_* columns.

Without u_*, ``wls`` falls back on the coherences, :func:`coherence_variances`.
"""

from __future__ import annotations

import numpy as np

from reduction.errors import ReductionError

DEFAULT_RECORDS = 50  # revolutions per averaged phasor assumed when a table has no n_records


def phasor_uncertainty(record_phasors, axis: int = 0) -> np.ndarray:
    """Standard uncertainty of the mean of per-record (per-revolution) complex phasors:
    sqrt(sum_s |q_s - q_mean|^2 / (n - 1)) / sqrt(n), along ``axis`` (inf for n = 1).

    The one formula for u_x, u_y, u_fx, u_fy of the orbit table (same unit as the phasors).
    """
    q = np.asarray(record_phasors, dtype=complex)
    if q.ndim == 0 or q.shape[axis] < 1:
        raise ReductionError("phasor_uncertainty needs at least one record along axis")
    n = q.shape[axis]
    if n == 1:
        return np.full(np.delete(q.shape, axis % q.ndim), np.inf)
    dev = q - np.mean(q, axis=axis, keepdims=True)
    scatter2 = np.sum(np.abs(dev) ** 2, axis=axis) / (n - 1)
    return np.sqrt(scatter2 / n)


def equation_variances(u: np.ndarray, Z: np.ndarray) -> np.ndarray:
    """Variances of the 4n real equations (rows Re fx, Im fx, Re fy, Im fy per frequency).

    u (n, 4): standard uncertainties of x, y (m), fx, fy (N); Z (n, 2, 2) the impedance
    (N/m) at each row. Each real part carries half of the complex residual's E|r|^2.
    """
    u = np.asarray(u, dtype=float)
    ud2 = u[:, :2] ** 2  # (n, 2)
    uf2 = u[:, 2:] ** 2
    var = uf2 + np.einsum("kij,kj->ki", np.abs(Z) ** 2, ud2)  # (n, 2) complex E|r|^2
    return np.repeat(var / 2, 2, axis=1).reshape(-1)


def coherence_variances(gamma2, fx, fy, n_records=None) -> np.ndarray:
    """Relative variances (any common scale) of the 4n real equations from the coherences.

    A force phasor of coherence gamma^2 with the motion has, per record, the noise-to-signal
    power rho = (1 - gamma^2) / gamma^2, and its average over n records the variance
    |f|^2 rho / n. For fx, gamma^2 is the mean of gamma2_xfx and gamma2_yfx (x and y are
    coherent with each other on a single-frequency orbit), likewise for fy.

    rho is floored at 1 / n: a coherence estimated from n records has a resolution (and a
    bias: its expectation is 1/n even for incoherent records) of order 1/n, so it cannot
    vouch for a smaller noise ratio. A row reading gamma^2 = 1.000 is therefore weighted like
    a row with rho = 1/n, not a million times heavier. n is ``DEFAULT_RECORDS`` when the table
    has no n_records.
    """
    g = np.asarray(gamma2, dtype=float)
    fx, fy = np.asarray(fx, dtype=complex), np.asarray(fy, dtype=complex)
    n = np.full(g.shape[0], float(DEFAULT_RECORDS)) if n_records is None else np.asarray(n_records, float)
    gx = np.clip((g[:, 0] + g[:, 1]) / 2, 1e-12, 1.0)
    gy = np.clip((g[:, 2] + g[:, 3]) / 2, 1e-12, 1.0)
    mag2 = np.stack([np.abs(fx) ** 2, np.abs(fy) ** 2], axis=1)
    mag2 = np.maximum(mag2, 1e-12 * max(float(np.mean(mag2)), np.finfo(float).tiny))
    rho = np.maximum(np.stack([(1 - gx) / gx, (1 - gy) / gy], axis=1), 1.0 / n[:, None])
    var = mag2 * rho / n[:, None]
    return np.repeat(var, 2, axis=1).reshape(-1)
