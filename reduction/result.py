"""The result of an identification and its JSON object (the orbit-table contract v3)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from reduction.arrays import ComplexArray, FloatArray
from reduction.impedance import forces, impedance
from reduction.models import ModelSpec
from reduction.selection import Selection
from reduction.statistics import Interval
from reduction.table import OrbitTable
from rigunits import coefficient_unit


@dataclass
class Identification:
    """Result of :func:`reduction.identify.identify` (SI: N/m, N s/m, kg, Omega in rad/s).

    ``coefficients`` / ``std_errors`` / ``confidence_95`` use the spec's keys (``Kxx``,
    ``Kxx_1``, ...; a symmetric pair appears under both keys, absorbed K orders not at all).
    ``free`` names the free coefficients in the order of ``theta`` and ``covariance``;
    ``dof`` = 4 n - p. ``chi2`` / ``p_value`` only when the table has u_* columns.
    ``exponent`` is the M chosen by power:auto. ``interval``: where the quantile of
    ``confidence_95`` comes from (normal with u_*, else student_t); ``not_determined``: the
    keys whose statistical expanded uncertainty k x std (k: statistics.coverage_factor, 2 with
    u_*) exceeds their magnitude. ``tls_ratio``: the noise ratio (N/m) of a tls fit without
    u_* (given, or its default), which its linear map for the type-B terms needs; else None.
    """

    model: str
    freq_dep: str
    method: str
    n_coefficients: int
    min_frequencies: int
    n_frequencies: int
    coefficients: dict[str, float]
    std_errors: dict[str, float | None]
    condition_number: float
    residual_rms: float
    fit: Sequence[dict[str, Any]]  # reduction.diagnostics.FitRows: one dict per row, read lazily
    spec: ModelSpec = field(repr=False)
    theta: FloatArray = field(repr=False)  # free coefficients, column order
    exponent: int | None = None
    solver: str = "qr"
    cost: float = field(default=float("nan"), repr=False)  # the estimator's minimised objective (RSS)
    skipped: dict[int, str] = field(default_factory=dict, repr=False)  # power:auto: M -> reason
    selection: Selection | None = field(default=None, repr=False)  # power:auto: the choice, for the adequacy test
    free: list[str] = field(default_factory=list)
    covariance: FloatArray | None = field(default=None, repr=False)  # (p, p) SI, or None
    dof: int = 0
    confidence_95: dict[str, tuple[float, float] | None] = field(default_factory=dict)
    chi2: float | None = None
    p_value: float | None = None
    aic: float = float("nan")
    bic: float = float("nan")
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    known_noise: bool = False  # covariance from the table's u_* columns (else from the residual)
    interval: Interval = Interval.STUDENT_T  # where the 95 % intervals' quantile comes from
    not_determined: list[str] = field(default_factory=list)
    tls_ratio: float | None = None  # N/m: the noise ratio sigma_f / sigma_d a tls fit without u_* weighed by

    @property
    def constant(self) -> bool:
        """A constant fit: no frequency dependence (``freq_dep`` none)."""
        return self.spec.freq_dep.constant

    def to_dict(self, fit: bool = True) -> dict[str, Any]:
        """The contract's JSON object (``exponent`` added for power:auto); NaN/inf -> None.
        ``fit=False`` leaves the per-row ``fit`` out (a long table's writer streams it)."""
        cov = None if self.covariance is None else [[_num(v) for v in row] for row in self.covariance]
        d: dict[str, Any] = {
            "model": self.model,
            "freq_dep": self.freq_dep,
            "method": self.method,
            "n_coefficients": self.n_coefficients,
            "min_frequencies": self.min_frequencies,
            "n_frequencies": self.n_frequencies,
            "coefficients": {k: _num(v) for k, v in self.coefficients.items()},
            "units": {k: coefficient_unit(k) for k in self.coefficients},
            "std_errors": {k: _num(v) for k, v in self.std_errors.items()},
            "confidence_95": {
                k: (None if v is None else [_num(v[0]), _num(v[1])]) for k, v in self.confidence_95.items()
            },
            "free": list(self.free),
            "covariance": cov,
            "dof": int(self.dof),
            "condition_number": _num(self.condition_number),
            "residual_rms": _num(self.residual_rms),
        }
        if self.chi2 is not None:
            d["chi2"], d["p_value"] = _num(self.chi2), _num(self.p_value)
        d.update(
            aic=_num(self.aic),
            bic=_num(self.bic),
            interval=str(self.interval),
            not_determined=list(self.not_determined),
            notes=list(self.notes),
            warnings=list(self.warnings),
            **({"fit": [{k: _num(v) for k, v in row.items()} for row in self.fit]} if fit else {}),
        )
        if self.exponent is not None:
            d["exponent"] = self.exponent
        return d

    def matrices(self, orbit: float) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(K, C, D) 2x2 at orbit frequency Omega (rad/s), summed over their fitted orders
        (K(Omega) = sum_r Omega^r K^(r)); D is zeros for a model without D."""
        w = float(orbit)
        out = {m: np.zeros((2, 2)) for m in "KCD"}
        for t, v in zip(self.spec.terms, self.theta):
            for i, j in t.entries:
                out[t.matrix][i, j] += v * w**t.order
        return out["K"], out["C"], out["D"]

    def impedance(self, orbit: ArrayLike) -> ComplexArray:
        """Z(Omega) = K + i Omega C - Omega^2 D, shape (n, 2, 2), N/m."""
        return impedance(self.spec, self.theta, orbit)

    def reproduce(self, table: OrbitTable) -> tuple[ComplexArray, ComplexArray]:
        """Reproduced force phasors (fx, fy), N, f = -Z(Omega) d from the table's displacements."""
        return forces(self.impedance(table.orbit), table.x, table.y)


def _num(v: Any) -> float | None:
    if v is None:
        return None
    v = float(v)
    return v if math.isfinite(v) else None
