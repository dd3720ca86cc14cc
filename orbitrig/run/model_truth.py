"""The truth each stored fit can be judged against: the simulator's true Z(Omega) projected
onto that fit's model structure.

A fit can only reach what its model can express: kc8 has no D, kcd11 forces D symmetric,
a constant model cannot follow a Z that changes with Omega. Comparing every fit with one
constant K, C, D best fit therefore blames the model's constraints on the data. The
projection used is the fit itself on noise-free data (reduction.expected.noise_free_fit):
the point's orbit table with its forces replaced by -Z_true d at the table's own
displacements, so the same rows, weights, constraints, frequency dependence and method.

Pure (no I/O); stored under the fit's JSON key ``truth`` ({"coefficients", "definition"}).
"""

from __future__ import annotations

from typing import Any
import numpy as np

from reduction.errors import ReductionError
from reduction.expected import noise_free_fit
from reduction.result import Identification
from reduction.table import OrbitTable

DEFINITION = (
    "the fit's model (constraints, frequency dependence, method, weights) identified on the "
    "point's orbit table with noise-free forces -Z_true d at the table's displacements"
)


def model_truth(ident: Identification, table: OrbitTable, z_true: np.ndarray) -> dict[str, Any]:
    """{"coefficients": {key: SI value}, "definition"} of fit ``ident`` (made from ``table``)
    against the true impedance ``z_true`` (n, 2, 2) complex at the table's rows (same order);
    {"error": reason} when the noise-free fit cannot be made."""
    try:
        return {"coefficients": noise_free_fit(ident, table, z_true), "definition": DEFINITION}
    except (ReductionError, np.linalg.LinAlgError, ValueError) as err:
        return {"error": str(err)}
