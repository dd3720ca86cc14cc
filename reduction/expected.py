"""What a fit would give without noise: its model identified on a table whose forces are
the exact f_bar = -Z d_bar of a known impedance Z(Omega).

Everything but the forces stays the table's: displacements, orbit speeds, coherences and
u_*, hence the same rows, weights, constraints, frequency dependence and method. The result
is the projection of Z onto the fit's model structure, the value its estimates scatter
about: the truth a model can reach (a simulator knows Z). Pure numpy; SI.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from reduction.identify import identify
from reduction.impedance import forces
from reduction.models import resolved_freq_dep
from reduction.result import Identification
from reduction.table import OrbitTable


def noise_free_fit(ident: Identification, table: OrbitTable, z: np.ndarray) -> dict[str, float]:
    """Coefficients (SI, keyed as ``ident``'s) of fit ``ident``, made from ``table``, repeated
    on the table's displacements with forces -Z d, ``z`` (n, 2, 2) complex N/m at the table's
    rows in order; power:auto at the exponent ``ident`` chose, tls at its noise ratio. Raises ReductionError when the
    model cannot be identified, ValueError when ``z`` does not match the rows."""
    z = np.asarray(z)
    if z.shape != (len(table.orbit), 2, 2):
        raise ValueError(f"the impedance has shape {z.shape}, the table {len(table.orbit)} rows")
    fx, fy = forces(z, table.x, table.y)
    freq_dep = resolved_freq_dep(ident.freq_dep, ident.exponent)
    exact = identify(
        dataclasses.replace(table, fx=fx, fy=fy),
        model=ident.model,
        freq_dep=freq_dep,
        method=ident.method,
        tls_ratio=ident.tls_ratio,  # tls without u_*: the fit's own noise ratio, not the exact forces' default
    )
    return {k: float(v) for k, v in exact.coefficients.items()}
