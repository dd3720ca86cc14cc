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
from reduction.systematic import CHANNELS, Budget, Calibration, calibration_covariance


@dataclass(frozen=True)
class Coverage:
    """Per coefficient key: the effective dof of the combined u (inf: every part exact), its k
    and U = k u_c (None where the combined u is unknown, a fit without covariance)."""

    dof: dict[str, float]
    k: dict[str, float]
    expanded: dict[str, float | None]


#: the calibration parameters whose u rest on one fit's residual: one part each (module docstring)
PARTS = (
    ("fx.gain", "fy.gain"),
    ("x.gain",),
    ("y.gain",),
    *((f"{c}.phase", f"{c}.delay") for c in CHANNELS),
    ("x.sensitivity", "y.sensitivity"),
)


def calibration_parts_of(labels: list[str]) -> list[list[str]]:
    """The parts (:data:`PARTS`) of the parameters ``labels``, each parameter in exactly one."""
    return [[n for n in part if n in labels] for part in PARTS if any(n in labels for n in part)]


def calibration_parts(calibration: Calibration) -> list[tuple[list[str], float]]:
    """(the error parameters of one part, its degrees of freedom: the smallest of its parameters')
    of ``calibration``, every parameter of Calibration.parameters in exactly one part (:data:`PARTS`)."""
    return [(list(part), min(_parameter_dof(calibration, n) for n in part)) for part in PARTS]


def _parameter_dof(calibration: Calibration, name: str) -> float:
    """The degrees of freedom of calibration parameter ``name`` ("fx.gain", "x.delay", ...): its
    channel's gain fit's or lag line's; the sensitivity's a certificate's (inf)."""
    channel, quantity = name.split(".")
    if quantity == "sensitivity":
        return math.inf
    c = getattr(calibration, channel)
    dof: float = c.gain_dof if quantity == "gain" else c.lag_dof
    return dof


def statistical_dof(ident: Identification) -> float:
    """The statistical part's degrees of freedom: inf with a known covariance (``interval``
    normal: the orbit table's u_* columns), else the fit's dof."""
    return math.inf if Interval(ident.interval) == Interval.NORMAL else float(ident.dof)


def source_dof(calibration: Calibration) -> dict[str, float]:
    """Each calibration parameter's degrees of freedom: its part's (:func:`calibration_parts`;
    inf: known exactly). What a stored budget keeps (``source_dof``) to rebuild the coverage."""
    return {name: dof for names, dof in calibration_parts(calibration) for name in names}


def combined_coverage(ident: Identification, budget: Budget, calibration: Calibration, runout_dof: float) -> Coverage:
    """The :class:`Coverage` of ``budget`` (uncertainty_budget of ``ident`` with ``calibration``,
    its runout's u with ``runout_dof``)."""
    _, sigma = calibration.parameters()
    runout = (budget.covariance_runout, runout_dof)
    nu, k = part_coverage(ident, budget.jacobian, budget.labels, sigma, source_dof(calibration), runout)
    expanded = {key: (None if c is None else k[key] * c) for key, c in budget.combined.items()}
    return Coverage(nu, k, expanded)


def part_coverage(
    ident: Identification,
    J: np.ndarray,
    labels: list[str],
    sigma: np.ndarray,
    dof: dict[str, float],
    runout: tuple[np.ndarray | None, float] = (None, math.inf),
) -> tuple[dict[str, float], dict[str, float]]:
    """(effective dof, k) per coefficient key of ``ident``'s combined u: its statistical part and
    the calibration parts of the parameters ``labels`` (Jacobian ``J``, standard uncertainties
    ``sigma``, each parameter's ``dof``: :func:`source_dof`; the parts as :func:`calibration_parts`
    groups them, a part's dof the smallest of its parameters'), and ``runout`` (its covariance, dof)."""
    sigma = np.asarray(sigma, dtype=float)
    variances, dofs = [], []
    for names in calibration_parts_of(labels):
        idx = [labels.index(n) for n in names]
        variances.append(np.diag(calibration_covariance(J[:, idx], sigma[idx], names)))
        dofs.append(min(dof[n] for n in names))
    if runout[0] is not None:
        variances.append(np.diag(runout[0]))
        dofs.append(runout[1])
    p = J.shape[0]
    variances.append(np.zeros(p) if ident.covariance is None else np.diag(ident.covariance))
    dofs.append(statistical_dof(ident))
    parts = [np.sqrt(np.clip(v, 0, None)) for v in variances]
    u_c = np.sqrt(sum((q**2 for q in parts), np.zeros(p)))
    nu = welch_satterthwaite(u_c, parts, dofs)
    nu_eff = {key: float(v) for key, v in ident.spec.expand(nu).items()}
    return nu_eff, {key: float(v) for key, v in ident.spec.expand(coverage_factors(nu)).items()}
