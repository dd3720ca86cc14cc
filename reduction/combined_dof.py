"""Coverage of the combined expanded uncertainty of the identified coefficients (GUM G.4, G.6).

The combined variance of a coefficient is its parts' sum: the fit's statistical one and the
calibration's (reduction.systematic.uncertainty_budget), each calibration part the contribution
of one fit of the calibration record. Each part comes with its degrees of freedom: the
statistical part infinite with a known covariance (u_* columns: ``interval`` normal, orbit-table
v3), else the fit's dof (4n - p); a calibration part its record's (:class:`ChannelCalibration`'s
``gain_dof``, ``lag_dof``; the runout's ``DisplacementTerm.dof``; inf for a certificate's, the
probes' sensitivity reference's). The effective dof is Welch-Satterthwaite's
(reduction.statistics.welch_satterthwaite), k Student's t at 95.45 % there
(reduction.statistics.coverage_factor, 2 where every part is known exactly; at the fractional
effective dof, not truncated: GUM G.4.1 allows either) and U = k u_c, per coefficient. Parameters whose u rest on one fit's residual are summed into one part before
(their variances are not independent estimates): a channel's phase and delay (one line), both
force channels' gains (one gain-matrix fit), x and y sensitivity (one reference).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from reduction.result import Identification
from reduction.statistics import Interval, coverage_factors, welch_satterthwaite
from reduction.systematic import CHANNELS, Budget, Calibration, _calibration_covariance


@dataclass(frozen=True)
class Coverage:
    """Per coefficient key: the effective dof of the combined u (inf: every part exact), its k
    and U = k u_c (None where the combined u is unknown, a fit without covariance)."""

    dof: dict[str, float]
    k: dict[str, float]
    expanded: dict[str, float | None]


def calibration_parts(calibration: Calibration) -> list[tuple[list[str], float]]:
    """(the error parameters of one part, its degrees of freedom) of ``calibration``, every
    parameter of Calibration.parameters in exactly one part."""
    ch = {c: getattr(calibration, c) for c in CHANNELS}
    parts = [(["fx.gain", "fy.gain"], min(ch["fx"].gain_dof, ch["fy"].gain_dof))]
    parts += [([f"{c}.gain"], ch[c].gain_dof) for c in ("x", "y")]
    parts += [([f"{c}.phase", f"{c}.delay"], ch[c].lag_dof) for c in CHANNELS]
    return parts + [(["x.sensitivity", "y.sensitivity"], math.inf)]


def statistical_dof(ident: Identification) -> float:
    """The statistical part's degrees of freedom: inf with a known covariance (``interval``
    normal: the orbit table's u_* columns), else the fit's dof."""
    return math.inf if Interval(ident.interval) == Interval.NORMAL else float(ident.dof)


def combined_coverage(ident: Identification, budget: Budget, calibration: Calibration, runout_dof: float) -> Coverage:
    """The :class:`Coverage` of ``budget`` (uncertainty_budget of ``ident`` with ``calibration``,
    its runout's u with ``runout_dof``)."""
    _, sigma = calibration.parameters()
    labels, J = budget.labels, budget.jacobian
    variances, dofs = [], []
    for names, part_dof in calibration_parts(calibration):
        idx = [labels.index(n) for n in names]
        variances.append(np.diag(_calibration_covariance(J[:, idx], sigma[idx], names)))
        dofs.append(part_dof)
    if budget.covariance_runout is not None:
        variances.append(np.diag(budget.covariance_runout))
        dofs.append(runout_dof)
    p = J.shape[0]
    variances.append(np.zeros(p) if ident.covariance is None else np.diag(ident.covariance))
    dofs.append(statistical_dof(ident))
    parts = [np.sqrt(np.clip(v, 0, None)) for v in variances]
    u_c = np.sqrt(sum((q**2 for q in parts), np.zeros(p)))
    nu = welch_satterthwaite(u_c, parts, dofs)
    nu_eff = {key: float(v) for key, v in ident.spec.expand(nu).items()}
    k = {key: float(v) for key, v in ident.spec.expand(coverage_factors(nu)).items()}
    expanded = {key: (None if c is None else k[key] * c) for key, c in budget.combined.items()}
    return Coverage(nu_eff, k, expanded)
