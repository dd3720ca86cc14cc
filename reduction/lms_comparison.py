"""The two load measuring systems' identifications of one operating point compared: the
difference of their free coefficients with its covariance (statistical of both fits; the
calibration's, the displacement channels shared and the force channels independent:
reduction.systematic's Jacobians), E_n per coefficient and the joint chi2 test at a
family-wise level (:class:`LmsAgreement`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from reduction import distributions as dist

from reduction.errors import ReductionError
from reduction.result import Identification
from reduction.statistics import joint_chi2
from reduction.systematic import (
    DISPLACEMENT_CHANNELS,
    Calibration,
    DisplacementTerm,
    calibration_covariance,
    displacement_jacobian,
    systematic_jacobian,
)
from reduction.table import OrbitTable


def lms_difference(
    a: Identification,
    table_a: OrbitTable,
    b: Identification,
    table_b: OrbitTable,
    calibration_a: Calibration,
    calibration_b: Calibration,
    runout: DisplacementTerm | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(a - b, its covariance) of the free coefficients of two load measuring systems'
    identifications of one operating point (same model; SI, free-coefficient order).

    The covariance is the statistical covariances of both fits (independent force noise)
    plus the systematic covariance of the difference: the displacement channels are shared,
    so their errors enter as J_a - J_b (``runout``'s too: the tables share x, y); the force
    channels' errors are independent.
    """
    if a.spec.names != b.spec.names or a.theta is None or b.theta is None:
        raise ReductionError("lms_consistency needs the same model and frequency dependence on both systems")
    labels, Ja = systematic_jacobian(a, table_a)
    _, Jb = systematic_jacobian(b, table_b)
    _, sa = calibration_a.parameters()
    _, sb = calibration_b.parameters()
    shared = np.array([lab.split(".")[0] in DISPLACEMENT_CHANNELS for lab in labels])
    Jd = Ja[:, shared] - Jb[:, shared]
    sd = (sa[shared] + sb[shared]) / 2  # one set of probes: the two configs should agree
    cov = (
        calibration_covariance(Jd, sd, [lab for lab, s in zip(labels, shared) if s])
        + (Ja[:, ~shared] * sa[~shared] ** 2) @ Ja[:, ~shared].T
        + (Jb[:, ~shared] * sb[~shared] ** 2) @ Jb[:, ~shared].T
    )
    if runout is not None:
        Jr = displacement_jacobian(a, table_a, runout) - displacement_jacobian(b, table_b, runout)
        cov = cov + Jr @ Jr.T
    for ident in (a, b):
        if ident.covariance is not None:
            cov = cov + ident.covariance
    return a.theta - b.theta, cov


def lms_consistency(
    a: Identification,
    table_a: OrbitTable,
    b: Identification,
    table_b: OrbitTable,
    calibration_a: Calibration,
    calibration_b: Calibration,
) -> dict[str, float | None]:
    """Normalised difference E_n = (a - b) / u(a - b) of every common coefficient of two load
    measuring systems' identifications (:func:`lms_difference`), one coefficient at a time.
    Whether the systems agree is judged for all coefficients at once (:func:`lms_agreement`)."""
    diff, cov = lms_difference(a, table_a, b, table_b, calibration_a, calibration_b)
    return _normalised(a, diff, cov)


def _normalised(a: Identification, diff: np.ndarray, cov: np.ndarray) -> dict[str, float | None]:
    u = np.sqrt(np.clip(np.diag(cov), 0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        en = np.where(u > 0, diff / np.where(u > 0, u, 1.0), np.nan)
    return {key: (None if not np.isfinite(v) else float(v)) for key, v in a.spec.expand(en).items()}


@dataclass(frozen=True)
class LmsAgreement:
    """The joint test of two load measuring systems: chi2 = d^T V^+ d of the difference d of
    all free coefficients with its covariance V (``dof`` its rank), against the (1 - level)
    quantile ``limit`` of chi2(dof). ``level`` is the family-wise false-flag probability:
    two consistent systems are flagged in that fraction of points, however many coefficients
    are compared. ``e_n`` per coefficient as :func:`lms_consistency`; chi2, limit, p_value
    None when nothing has an uncertainty."""

    e_n: dict[str, float | None]
    chi2: float | None
    dof: int
    level: float
    limit: float | None
    p_value: float | None

    @property
    def consistent(self) -> bool:
        return self.chi2 is not None and self.limit is not None and self.chi2 <= self.limit

    @property
    def max_abs(self) -> float | None:
        values = [abs(v) for v in self.e_n.values() if v is not None]
        return max(values) if values else None

    def e_n_limit(self) -> float | None:
        """|E_n| beyond which one coefficient alone is unlikely at the family-wise level
        (Sidak: two-sided normal quantile at 1 - (1 - level)^(1/dof)); for marking tables."""
        if self.dof == 0:
            return None
        return float(dist.norm_isf((1 - (1 - self.level) ** (1 / self.dof)) / 2))


LMS_LEVEL = 0.05  # family-wise probability that two consistent systems are flagged


def lms_agreement(
    a: Identification,
    table_a: OrbitTable,
    b: Identification,
    table_b: OrbitTable,
    calibration_a: Calibration,
    calibration_b: Calibration,
    level: float = LMS_LEVEL,
    runout: DisplacementTerm | None = None,
) -> LmsAgreement:
    """Whether two load measuring systems agree on all coefficients at once, at the
    family-wise ``level`` (default 5 %): chi2 of the joint difference with its covariance
    (:class:`LmsAgreement`; ``runout`` as in :func:`lms_difference`). Exact for linear fits
    with stated noise (u_* columns) and a stated calibration; with covariances estimated from the residuals it is approximate
    (more false flags with few residual degrees of freedom)."""
    if not 0 < level < 1:
        raise ReductionError(f"lms_agreement: level must be in (0, 1), got {level!r}")
    diff, cov = lms_difference(a, table_a, b, table_b, calibration_a, calibration_b, runout)
    en = _normalised(a, diff, cov)
    chi2, dof = joint_chi2(diff, cov)
    if dof == 0 or not np.isfinite(chi2):
        return LmsAgreement(en, None, 0, level, None, None)
    return LmsAgreement(en, float(chi2), dof, level, dist.chi2_isf(level, dof), dist.chi2_sf(float(chi2), dof))
