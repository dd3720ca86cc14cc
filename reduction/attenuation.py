"""Errors-in-variables bias of ols and wls: noisy displacements attenuate the coefficients.

With displacement noise the regression matrix A is measured, not known: E[A^T W A] exceeds
the noise-free one by Sigma_W = sum over rows k, forces i, displacements l of
w_k,i u_k,l^2 Re(e e^H), e = E[k, :, i, l] the impedance basis column (u the standard
uncertainty sqrt(E|e|^2) of the averaged phasor, w the equation weights, 1 for ols). To
first order the estimate is pulled towards zero by

    bias = -(A^T W A)^-1 Sigma_W theta,

which for circles of radius R and noise u is about -theta u^2 / R^2 on the direct terms.
It does not shrink with more rows while the standard error does, so the fit is warned when
a coefficient's bias exceeds ``EIV_BIAS_FRACTION`` of its standard error (a 95 % interval
then covers about 94 % instead of 95 %), naming tls and iv, which remove it. Needs the
displacement noise, i.e. the table's u_x, u_y. Everything SI, no I/O.
"""

from __future__ import annotations

import numpy as np

from reduction.errors import ReductionError
from reduction.impedance import impedance_columns
from reduction.models import ModelSpec
from reduction.table import OrbitTable

EIV_BIAS_FRACTION = 0.25  # warn when |bias| > 0.25 standard errors
LISTED = 8
ROWS = 65536  # rows per block of the noise sum


def attenuation_bias(
    spec: ModelSpec,
    table: OrbitTable,
    theta: np.ndarray,
    scale: np.ndarray,
    unscaled: np.ndarray,
    weights: np.ndarray | None = None,
) -> np.ndarray:
    """(p,) first-order bias (SI, column order) of ols (``weights`` None) or wls (weights
    (4n,) the inverse equation variances) from the table's displacement noise u_x, u_y;
    ``unscaled`` is (A_s^T W A_s)^-1 of the column-scaled (by ``scale``) regression."""
    if table.u is None:
        raise ReductionError("attenuation_bias needs the table's u_x, u_y (displacement noise)")
    u = table.u
    w = np.ones((table.n, 2)) if weights is None else np.asarray(weights).reshape(table.n, 2, 2)[:, :, 0]
    p = spec.n_coefficients
    filling: dict[tuple[int, int], list[int]] = {}  # Z's entry (i, l) -> the coefficients whose basis fills it
    for j, t in enumerate(spec.terms):
        for i, l in t.entries:
            filling.setdefault((i, l), []).append(j)
    sigma = np.zeros((p, p))
    for s in range(0, table.n, ROWS):
        cols = impedance_columns(spec, table.orbit[s : s + ROWS])
        for (i, l), J in filling.items():
            e = cols[:, J]
            weight = w[s : s + ROWS, i] * u[s : s + ROWS, l] ** 2
            sigma[np.ix_(J, J)] += (np.conj(e).T @ (e * weight[:, None])).real
    sigma_s = sigma / np.outer(scale, scale)
    bias: np.ndarray = -(unscaled @ (sigma_s @ (theta * scale))) / scale
    return bias


def attenuation_warning(spec: ModelSpec, method: str, bias: np.ndarray, std: np.ndarray) -> str | None:
    """The warning when a coefficient's attenuation bias exceeds ``EIV_BIAS_FRACTION`` of
    its standard error, or None."""
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.abs(bias) / std
    ratio = np.where(np.isfinite(ratio), ratio, 0.0)
    if not np.max(ratio, initial=0.0) > EIV_BIAS_FRACTION:
        return None
    order = [j for j in np.argsort(-ratio) if ratio[j] > EIV_BIAS_FRACTION]
    listed = ", ".join(f"{spec.names[j]} ({ratio[j]:.2g} SE)" for j in order[:LISTED])
    more = f" and {len(order) - LISTED} more" if len(order) > LISTED else ""
    return (
        f"displacement noise: {method} is biased towards zero (errors in variables, about u_d^2 / R^2 "
        f"relative) by more than {EIV_BIAS_FRACTION:g} standard errors on {listed}{more}; "
        "--method tls (or iv) removes that bias."
    )
