"""The truth each stored fit can be judged against: the simulator's true Z(Omega) projected
onto that fit's model structure.

A fit can only reach what its model can express: kc8 has no D, kcd11 forces D symmetric,
a constant model cannot follow a Z that changes with Omega. Comparing every fit with one
constant K, C, D best fit therefore blames the model's constraints on the data. The
projection used here is the fit itself, run on noise-free data: the point's orbit table
with its forces replaced by f_bar = -Z_true d_bar at the table's own displacements, orbit
speeds, coherences and u_* (so the same rows, the same weights, the same constraints and
frequency dependence, the same method; power:auto at the exponent the fit chose). What the
fit's coefficients would be without noise and calibration errors: their expected value.

Pure (no I/O); stored under the fit's JSON key ``truth`` ({"coefficients", "definition"}).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from reduction.errors import ReductionError
from reduction.identify import identify
from reduction.impedance import forces
from reduction.result import Identification
from reduction.table import OrbitTable

DEFINITION = ("the fit's model (constraints, frequency dependence, method, weights) identified on the "
              "point's orbit table with noise-free forces -Z_true d at the table's displacements")  # fmt: skip


def model_truth(ident: Identification, table: OrbitTable, z_true: np.ndarray) -> dict:
    """{"coefficients": {key: SI value}, "definition"} of fit ``ident`` (made from ``table``)
    against the true impedance ``z_true`` (n, 2, 2) complex at the table's rows (same order);
    {"error": reason} when the noise-free fit cannot be made."""
    freq_dep = f"power:{ident.exponent}" if ident.freq_dep == "power:auto" else ident.freq_dep
    try:
        fx, fy = forces(np.asarray(z_true), table.x, table.y)
        exact = identify(dataclasses.replace(table, fx=fx, fy=fy), model=ident.model, freq_dep=freq_dep,
                         method=ident.method)  # fmt: skip
    except (ReductionError, np.linalg.LinAlgError, ValueError) as err:
        return {"error": str(err)}
    return {"coefficients": {k: float(v) for k, v in exact.coefficients.items()}, "definition": DEFINITION}
