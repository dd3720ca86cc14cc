"""The iv estimator's instruments: per row, the circle of the row's dominant whirl direction
(leave-one-out mean radius of that direction), and the regression on those circles.

An instrument must be correlated with the measured displacements but not with their noise;
the circle a row's direction has on the other rows of that direction is (reduction.identify).
"""

from __future__ import annotations

import numpy as np

from reduction.arrays import ComplexArray, FloatArray
from reduction.errors import IdentificationError
from reduction.impedance import real_rows, regressors
from reduction.models import ModelSpec
from reduction.rank import numerical_rank
from reduction.table import OrbitTable

IV_MAX_MISFIT = 0.3  # rms |d - circle| / rms |d| above which the circle instruments are refused


def circle_orbits(table: OrbitTable) -> tuple[ComplexArray, ComplexArray]:
    """The iv instruments' orbits: per row, the circle of the row's dominant whirl direction
    whose complex radius is the mean of that direction's dominant component over the OTHER
    rows of the same direction (leave-one-out). Returns (x_hat, y_hat), m."""
    a_f, a_b = table.whirl_components()
    forward = np.abs(a_f) >= np.abs(a_b)
    a = np.where(forward, a_f, a_b)
    x_hat = np.empty(table.n, dtype=complex)
    for direction in (True, False):
        rows = np.flatnonzero(forward == direction)
        if rows.size == 1:
            raise IdentificationError(
                "iv needs at least two orbits of each whirl direction present "
                "(the instruments are leave-one-out circles)"
            )
        if rows.size:
            x_hat[rows] = (np.sum(a[rows]) - a[rows]) / (rows.size - 1)
    y_hat: ComplexArray = np.where(forward, -1j, 1j) * x_hat
    return x_hat, y_hat


def circle_instruments(spec: ModelSpec, table: OrbitTable, rank_rtol: float) -> FloatArray:
    """(4n, p) the regression rows of the rows' circles (:func:`circle_orbits`): the instruments
    of two-stage least squares; IdentificationError when the orbits are too far from circles or
    the circles cannot separate the model's coefficients."""
    x_hat, y_hat = circle_orbits(table)
    misfit = np.sqrt(
        np.mean(np.abs(table.x - x_hat) ** 2 + np.abs(table.y - y_hat) ** 2)
        / np.mean(np.abs(table.x) ** 2 + np.abs(table.y) ** 2)
    )
    if misfit > IV_MAX_MISFIT:
        raise IdentificationError(
            f"iv: the orbits are not circles of common radius and trigger phase (misfit {100 * misfit:.0f} % "
            f"> {100 * IV_MAX_MISFIT:.0f} %), so the circle instruments do not fit this table; use --method tls"
        )
    Z = real_rows(regressors(spec, table.orbit, x_hat, y_hat))
    if numerical_rank(Z, rank_rtol).deficiency:
        raise IdentificationError(
            "iv: the circular-orbit instruments cannot separate this model's coefficients "
            "(e.g. a single whirl direction); use --method tls"
        )
    return Z
