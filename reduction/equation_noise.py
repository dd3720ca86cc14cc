"""The noise of an identification's equations (4 real equations per orbit frequency): their
variances for weighting, from the table's u_* columns (effective variances: force noise plus
displacement noise through Z, :func:`reduction.noise.equation_variances`) or, for wls without
u_*, from the coherences; and chi2 against u_* (dimensionless).
"""

from __future__ import annotations

import numpy as np

from reduction import regression as reg
from reduction.arrays import FloatArray
from reduction.errors import IdentificationError
from reduction.impedance import impedance
from reduction.methods import Method
from reduction.models import ModelSpec
from reduction.noise import coherence_variances, equation_variances
from reduction.table import OrbitTable


def variances(spec: ModelSpec, table: OrbitTable, theta0: FloatArray, b: FloatArray, method: str) -> FloatArray:
    """Variances of the 4n equations: from u_* (effective, at a first ols fit), else from the
    coherences for wls, else ones."""
    if table.u is not None:
        if not np.any(table.u[:, 2:] > 0) and not np.any(table.u[:, :2] > 0):
            raise IdentificationError(
                f"every row (all {table.n}), columns 'u_x', 'u_y', 'u_fx', 'u_fy': all zero, so there is "
                "no noise to weight by; state the standard uncertainties, or leave the u_* columns out"
            )
        var = effective_variances(spec, table.u, table, theta0)
        if not np.max(var) > 0:
            raise IdentificationError("the table's u_* give no noise on any equation")
        return var
    if method != Method.WLS:
        return np.ones(b.shape)
    if table.gamma2 is None:
        raise IdentificationError(
            "--method wls needs u_x, u_y, u_fx, u_fy columns or coherence values (gamma2_xfx, gamma2_yfx, "
            "gamma2_xfy, gamma2_yfy); the table has neither"
        )
    return coherence_variances(table.gamma2, table.fx, table.fy, table.n_records)


def effective_variances(spec: ModelSpec, u: FloatArray, table: OrbitTable, theta: FloatArray) -> FloatArray:
    """Effective variances of the 4n equations from u_* at ``theta``, floored at 1e-12 of the
    largest (computed over blocks of rows: a long table's temporaries stay small)."""
    rows = reg.CHUNK_ROWS // 4
    var = np.empty(4 * table.n)
    for s in range(0, table.n, rows):
        var[4 * s : 4 * (s + rows)] = equation_variances(
            u[s : s + rows], impedance(spec, theta, table.orbit[s : s + rows])
        )
    floored: FloatArray = np.maximum(var, 1e-12 * float(np.max(var)), out=var)
    return floored


def fit_chi2(
    spec: ModelSpec,
    u: FloatArray,
    table: OrbitTable,
    A_s: FloatArray,
    b: FloatArray,
    c: FloatArray,
    var: FloatArray,
    method: str,
    est: reg.Estimate,
) -> float:
    """chi2 against u_*: tls's own maximum-likelihood cost; for ols, wls and iv the weighted
    residual sum at the wls solution (the two passes of the wls branch from the first-pass
    variances ``var``), with the effective variances there. The ols or iv residual weighted by
    1/var is no chi2(dof): they do not minimise it, and with unequal variances it exceeds dof."""
    if method == Method.TLS:
        return float(est.rss)
    x = est.x
    for _ in range(0 if method == Method.WLS else 2):  # as reg.wls solves it, without its covariance
        x = reg.weighted_lstsq(A_s, b, np.sqrt(1.0 / var))  # blocked: no weighted copy of a long table
        var = effective_variances(spec, u, table, x / c)
    r = A_s @ x  # the weighted residual sum, in place (one vector of the table's length)
    np.subtract(b, r, out=r)
    r *= r
    r /= effective_variances(spec, u, table, x / c)
    return float(np.sum(r))
