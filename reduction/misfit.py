"""What a model leaves out moves with the frequency list.

A model without a term the bearing has (kc8 has no D: its K absorbs -Omega^2 D) estimates,
on noise-free data, the weighted least-squares projection of the richer model's forces onto
its own columns - and that projection depends on where the orbit frequencies lie and how
many revolutions each averages. Moving to a designed list therefore shifts the estimates by

    shift = (P_b - P_a) A_rich theta_rich,   P = (A^T W A)^-1 A^T W   (rows of the small model)

where a and b are the two lists, W their weights (per-revolution noise / revolutions) and
theta_rich the richer model's coefficients. The shift is linear in theta_rich, so its
standard uncertainty follows from the richer fit's covariance. Everything SI, no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from reduction.design import design_orbits
from reduction.impedance import impedance, real_rows, regressors
from reduction.models import ModelSpec
from reduction.noise import equation_variances
from reduction.rig_time import Ways, blocks_per_ratio
from reduction.whirl import Directions
from rigunits import HZ


#: a frequency list: (ratios, revolutions (one or per ratio), per-revolution noise u (4,) or (k, 4))
DesignList = tuple[ArrayLike, ArrayLike, ArrayLike]


@dataclass(frozen=True)
class ListShift:
    """Expected change (p,) of the small model's coefficients (SI, its column order) from
    list a to list b on the richer model's forces at theta_rich, and its standard
    uncertainty (p,) from theta_rich's covariance."""

    shift: np.ndarray
    std: np.ndarray


def _projection(
    small: ModelSpec,
    rich: ModelSpec,
    theta_rich: ArrayLike,
    spin: float,
    radius: float,
    ratios: ArrayLike,
    revolutions: ArrayLike,
    u_revolution: ArrayLike,
    directions: Ways,
) -> np.ndarray:
    """(p_small, p_rich): the small model's WLS estimate per unit of each rich coefficient
    (``directions`` one for every ratio or one per ratio)."""
    r = np.asarray(ratios, dtype=float)
    per = blocks_per_ratio(r.size, directions).astype(int)
    orbit, x, y = design_orbits(r * spin / HZ, directions, radius)
    n = np.repeat(np.broadcast_to(np.asarray(revolutions, dtype=float), r.shape), per)
    u = np.repeat(np.broadcast_to(np.asarray(u_revolution, dtype=float), (r.size, 4)), per, axis=0)
    var = equation_variances(u / np.sqrt(n)[:, None], impedance(rich, np.asarray(theta_rich, float), orbit))
    w = 1.0 / var
    A = real_rows(regressors(small, orbit, x, y))
    B = real_rows(regressors(rich, orbit, x, y))
    projection: np.ndarray = np.linalg.solve(A.T @ (A * w[:, None]), A.T @ (B * w[:, None]))
    return projection


def list_shift(
    small: ModelSpec,
    rich: ModelSpec,
    theta_rich: ArrayLike,
    cov_rich: ArrayLike,
    spin: float,
    radius: float,
    list_a: DesignList,
    list_b: DesignList,
    directions: Ways = Directions.BOTH,
    directions_b: Ways | None = None,
) -> ListShift:
    """Expected shift of ``small``'s estimates from list a to list b; a list is (ratios,
    revolutions (one or per ratio), per-revolution noise u (4,) or (k, 4) of x, y (m), fx,
    fy (N)); theta_rich, cov_rich: the richer model's coefficients and covariance (SI);
    ``directions`` list a's (one for every ratio or one per ratio), ``directions_b`` list b's
    (None: ``directions``)."""
    ways_b = directions if directions_b is None else directions_b
    J = _projection(small, rich, theta_rich, spin, radius, *list_b, ways_b) - _projection(
        small, rich, theta_rich, spin, radius, *list_a, directions
    )
    shift = J @ np.asarray(theta_rich, dtype=float)
    std = np.sqrt(np.clip(np.einsum("ij,jk,ik->i", J, np.asarray(cov_rich, dtype=float), J), 0.0, None))
    return ListShift(shift, std)
