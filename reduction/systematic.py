"""Systematic (type B) uncertainty of the coefficients from the channels' calibration.

Model of a calibration error, per channel c in x, y (displacement probes), fx, fy (load cells):
the measured phasor is q_c (1 + g_c) exp(-i (phi_c + Omega tau_c)): a relative gain error g_c, a
phase error phi_c (rad), a time delay tau_c (s); the probes' sensitivity error s, one for x and y
(the probe calibration's reference), acts like a gain on both. Each error is fixed for a run (the
same on every row), its standard uncertainty the rig's stated one (:class:`Calibration`).

Propagation is LINEARISED (first order; no Monte Carlo): a data change moves the estimate by
d theta = P (d b - d A theta), P the fit's map as the fit was done (:func:`fit_map`), d b - d A theta
the real rows of (d f + Z d d), plus the map's own change times the residual (:func:`map_change`).
The Jacobian J (one column per error parameter) gives cov_sys = J Sigma J^T (Sigma diagonal but
for the sensitivity's x and y, fully correlated). Hand checks: a gain error g on both force channels
scales K, C, D by 1 + g; a delay tau on them moves D by about -C tau (and C by -K tau); a
sensitivity error s scales every coefficient by 1 - s.

A displacement error common to every row of a point (the probes' runout subtracted from each
block: :class:`DisplacementTerm`, its change of each row's x, y per standard uncertainty of each
source) enters through the same P, fully correlated across the rows: J_r = P real_rows(Z dd), its
covariance J_r J_r^T added to the systematic one (``Budget.runout``: its standard uncertainty alone).

Statistical, systematic and combined (sum of the covariances) standard uncertainties are kept apart;
the expanded uncertainty U = k u_c and its k, per coefficient at the effective dof of the parts, are
reduction.combined_dof's (combined_coverage).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np

from reduction.errors import ReductionError
from reduction.identify import Method, tls_variances
from reduction.impedance import impedance_basis, real_operator, real_rows
from reduction.instruments import circle_instruments
from reduction.noise import coherence_variances, equation_variances
from reduction.rank import RANK_RTOL
from reduction.regression import residual_covariances
from reduction.result import Identification
from reduction.statistics import pseudo_inverse
from reduction.table import OrbitTable

CHANNELS = ("x", "y", "fx", "fy")
DISPLACEMENT_CHANNELS = ("x", "y")


@dataclass(frozen=True)
class ChannelCalibration:
    """Standard uncertainties of one channel's calibration: gain (relative), phase (rad), delay
    (s); the degrees of freedom of the gain's and of the phase's and delay's (one line) (inf: exact)."""

    gain: float = 0.0
    phase: float = 0.0
    delay: float = 0.0
    gain_dof: float = math.inf
    lag_dof: float = math.inf


@dataclass(frozen=True)
class Calibration:
    """Calibration uncertainty of the four channels of one orbit table; ``sensitivity`` is
    the displacement probes' relative sensitivity uncertainty, one error common to every probe
    (the probe calibration's reference): x.sensitivity and y.sensitivity fully correlated."""

    x: ChannelCalibration = field(default_factory=ChannelCalibration)
    y: ChannelCalibration = field(default_factory=ChannelCalibration)
    fx: ChannelCalibration = field(default_factory=ChannelCalibration)
    fy: ChannelCalibration = field(default_factory=ChannelCalibration)
    sensitivity: float = 0.0

    def parameters(self) -> tuple[list[str], np.ndarray]:
        """(labels, standard uncertainties) of every error parameter, e.g. "fx.delay"."""
        labels, values = list[str](), list[float]()
        for c in CHANNELS:
            ch = getattr(self, c)
            for kind in ("gain", "phase", "delay") + (("sensitivity",) if c in DISPLACEMENT_CHANNELS else ()):
                labels.append(f"{c}.{kind}")
                values.append(self.sensitivity if kind == "sensitivity" else getattr(ch, kind))
        sigma = np.array(values, dtype=float)
        if not np.all(np.isfinite(sigma)) or np.any(sigma < 0):
            raise ReductionError("calibration uncertainties must be finite and >= 0")
        return labels, sigma


@dataclass(frozen=True)
class DisplacementTerm:
    """Errors of the displacement phasors common to every row of a table (type B, each source
    fully correlated across the rows): ``labels`` (q,) the sources, ``dd`` (n, 2, q) complex the
    change of each row's (x, y) (m) by one standard uncertainty of each source; ``dof`` their u's."""

    labels: list[str]
    dd: np.ndarray
    dof: float = math.inf


class UncertaintyBasis(StrEnum):
    """The standard uncertainty a stored result rests on (its ``basis``: the expanded uncertainty
    and the two load measuring systems' comparison; the value is the stored text)."""

    COMBINED = "combined"  # statistical and the rig's stated calibration uncertainty (a Budget's)
    STATISTICAL = "statistical"  # the fit's statistical uncertainty only (no calibration stated)


@dataclass
class Budget:
    """Uncertainty budget of one identification (keys as ``Identification.coefficients``): standard uncertainties
    statistical / systematic / combined; covariances, the Jacobian (U and its k: combined_dof.combined_coverage)."""

    statistical: dict[str, float | None]
    systematic: dict[str, float]
    combined: dict[str, float | None]
    covariance_systematic: np.ndarray
    covariance_combined: np.ndarray | None
    labels: list[str]
    jacobian: np.ndarray  # (p, q): d theta / d beta
    runout: dict[str, float] = field(default_factory=dict)  # the DisplacementTerm's part alone
    covariance_runout: np.ndarray | None = None  # inside covariance_systematic


def systematic_jacobian(ident: Identification, table: OrbitTable) -> tuple[list[str], np.ndarray]:
    """(labels, J): d theta / d beta (p, q) for every calibration error parameter (unit errors:
    relative gain 1, phase 1 rad, delay 1 s), linearised at the fit (:func:`map_change` included)."""
    Z, P, var = fit_map(ident, table)
    d = {"x": table.x, "y": table.y, "fx": table.fx, "fy": table.fy}
    factors = {"gain": 1.0, "phase": -1j, "delay": -1j * table.orbit, "sensitivity": 1.0}  # d q / q per unit error
    labels, cols, dds = [], [], []
    zero = np.zeros(table.n, dtype=complex)
    for c in CHANNELS:
        for kind in ("gain", "phase", "delay") + (("sensitivity",) if c in DISPLACEMENT_CHANNELS else ()):
            dq = d[c] * factors[kind]
            dds.append(np.stack([dq if c == "x" else zero, dq if c == "y" else zero], axis=1))
            df = np.stack([dq if c == "fx" else zero, dq if c == "fy" else zero], axis=1)
            cols.append(real_rows(df + np.einsum("kij,kj->ki", Z, dds[-1])))  # d f + Z d d
            labels.append(f"{c}.{kind}")
    return labels, P @ np.stack(cols, axis=1) + map_change(ident, table, Z, P, var, np.stack(dds, axis=2))


def map_change(
    ident: Identification, table: OrbitTable, Z: np.ndarray, P: np.ndarray, var: np.ndarray | None, dd: np.ndarray
) -> np.ndarray:
    """(p, q) the part of d theta a displacement error dd (n, 2, q) makes through the fit's own map,
    (A^T W A)^-1 dA^T W r with the fit's residual r and weights W = 1 / var (:func:`fit_map`'s: ols,
    wls; on u_* their motion with theta is negligible); zeros without var (tls, iv: theirs needs the
    weights' or instruments' own change; 0.2 % of the statistical u at most, docs/orbit-table.md)."""
    if var is None:
        return np.zeros((P.shape[0], dd.shape[2]))
    d, f = np.stack([table.x, table.y], axis=1), np.stack([table.fx, table.fy], axis=1)
    r = real_rows(f + np.einsum("kij,kj->ki", Z, d))  # b - A theta
    dA = real_rows(-np.einsum("kpil,klq->kipq", impedance_basis(ident.spec, table.orbit), dd))  # (4n, p, q)
    out: np.ndarray = (P * var) @ P.T @ np.einsum("mpq,m->pq", dA, r / var)
    return out


def fit_map(ident: Identification, table: OrbitTable) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(Z (n, 2, 2) at the fit, P (p, 4n), the equations' variances (4n,) of ols and wls, else None):
    the fit's linear map of its real equation rows, as the fit was done: ols equal weights (whatever
    the u_* columns), wls its weights (u_* effective variances at the fit, else the coherences), iv
    its two stages (unweighted, the default rank tolerance), tls each row whitened by its residual's
    2 x 2 covariance at the fit (without u_* at its own noise ratio, ``Identification.tls_ratio``).
    Every type-B term goes through it."""
    Z, n = ident.impedance(table.orbit), table.n  # (n, 2, 2)
    A = real_rows(-np.einsum("kpil,kl->kip", impedance_basis(ident.spec, table.orbit), np.stack([table.x, table.y], 1)))
    if ident.method == Method.TLS:
        M = residual_covariances(Z, *tls_variances(table, ident.tls_ratio))  # (n, 2, 2) at the fit
        W = real_operator(np.linalg.inv(np.linalg.cholesky(M)))
        P = pseudo_inverse(np.einsum("kij,kjp->kip", W, A.reshape(n, 4, -1)).reshape(4 * n, -1))
        return Z, np.einsum("pki,kij->pkj", P.reshape(len(P), n, 4), W).reshape(len(P), -1), None
    if ident.method == Method.IV:  # two stages, unweighted: A projected onto the instruments' span
        Q, _ = np.linalg.qr(circle_instruments(ident.spec, table, RANK_RTOL))
        return Z, pseudo_inverse(Q @ (Q.T @ A)), None
    var = _fit_variances(ident, table, Z)
    return Z, pseudo_inverse(A / np.sqrt(var)[:, None]) / np.sqrt(var)[None, :], var


def displacement_jacobian(ident: Identification, table: OrbitTable, term: DisplacementTerm) -> np.ndarray:
    """(p, q) J_r = P real_rows(Z dd) + :func:`map_change`: the free coefficients' change for one standard
    uncertainty of each source of ``term`` (linearised), each common to every row; P the fit's map."""
    dd = np.asarray(term.dd, dtype=complex)
    if dd.shape != (table.n, 2, len(term.labels)):
        raise ReductionError(f"displacement term: dd has shape {dd.shape}, want ({table.n}, 2, {len(term.labels)})")
    Z, P, var = fit_map(ident, table)
    J: np.ndarray = P @ real_rows(np.einsum("kij,kjq->kiq", Z, dd)) + map_change(ident, table, Z, P, var, dd)
    return J


def displacement_covariance(ident: Identification, table: OrbitTable, term: DisplacementTerm) -> np.ndarray:
    """(p, p) covariance of the free coefficients from ``term``: J_r J_r^T (displacement_jacobian)."""
    J = displacement_jacobian(ident, table, term)
    cov: np.ndarray = J @ J.T
    return cov


def uncertainty_budget(
    ident: Identification,
    table: OrbitTable,
    calibration: Calibration,
    *,
    runout: DisplacementTerm | None = None,
) -> Budget:
    """Statistical (the fit's covariance), systematic (calibration, linearised; with ``runout``
    its common displacement errors too) and combined standard uncertainties of every
    coefficient (their U and k: reduction.combined_dof.combined_coverage)."""
    labels, J, cov_sys = _systematic_covariance(ident, table, *calibration.parameters())
    cov_run = None if runout is None else displacement_covariance(ident, table, runout)
    if cov_run is not None:
        cov_sys = cov_sys + cov_run
    cov_comb = None if ident.covariance is None else ident.covariance + cov_sys
    systematic = _standard(ident, cov_sys)
    combined: dict[str, float | None] = {key: None for key in systematic}
    combined.update({} if cov_comb is None else _standard(ident, cov_comb))
    run = {} if cov_run is None else _standard(ident, cov_run)
    return Budget(dict(ident.std_errors), systematic, combined, cov_sys, cov_comb, labels, J, run, cov_run)


def _standard(ident: Identification, cov: np.ndarray) -> dict[str, float]:
    """The standard uncertainty of every coefficient key of ``ident`` from a covariance of its free ones."""
    return {key: float(v) for key, v in ident.spec.expand(np.sqrt(np.clip(np.diag(cov), 0, None))).items()}


def combined_covariance(
    ident: Identification,
    table: OrbitTable,
    labels: list[str],
    sigma: np.ndarray,
    runout_covariance: np.ndarray | None = None,
) -> np.ndarray | None:
    """The combined covariance of :func:`uncertainty_budget` (``Budget.covariance_combined``,
    SI) from a stored budget's calibration parameters ``labels`` and their stated standard
    uncertainties ``sigma``: the fit's covariance plus J diag(sigma^2) J^T, plus a stored
    ``runout_covariance`` (``Budget.covariance_runout``); None without the fit's covariance."""
    _, _, cov_sys = _systematic_covariance(ident, table, labels, sigma)
    if runout_covariance is not None:
        run = np.asarray(runout_covariance, dtype=float)
        if run.shape != cov_sys.shape:
            raise ReductionError(f"runout covariance {run.shape} is not this fit's {cov_sys.shape}")
        cov_sys = cov_sys + run
    return None if ident.covariance is None else ident.covariance + cov_sys


def _systematic_covariance(
    ident: Identification, table: OrbitTable, names: list[str], sigma: np.ndarray
) -> tuple[list[str], np.ndarray, np.ndarray]:
    """(labels, J, J diag(sigma^2) J^T) of the calibration parameters ``names`` with standard
    uncertainties ``sigma``; ReductionError when they are not the Jacobian's."""
    labels, J = systematic_jacobian(ident, table)
    if list(names) != labels:
        raise ReductionError("calibration parameters do not match the Jacobian's")
    return labels, J, calibration_covariance(J, np.asarray(sigma, dtype=float), labels)


def calibration_covariance(J: np.ndarray, sigma: np.ndarray, labels: list[str]) -> np.ndarray:
    """J diag(sigma^2) J^T with the cross term of x.sensitivity and y.sensitivity (one error)."""
    Js = J * sigma
    cov: np.ndarray = Js @ Js.T
    if "x.sensitivity" in labels and "y.sensitivity" in labels:
        cross = np.outer(Js[:, labels.index("x.sensitivity")], Js[:, labels.index("y.sensitivity")])
        cov = cov + cross + cross.T
    return cov


def _fit_variances(ident: Identification, table: OrbitTable, Z: np.ndarray) -> np.ndarray:
    """The equation variances an ols or wls fit weighted by (relative scale irrelevant): ones for ols."""
    if ident.method == Method.OLS:
        return np.ones(4 * table.n)
    if table.u is not None:
        var = equation_variances(table.u, Z)
        return np.maximum(var, 1e-12 * float(np.max(var)))
    if ident.method == Method.WLS and table.gamma2 is not None:
        return coherence_variances(table.gamma2, table.fx, table.fy, table.n_records)
    return np.ones(4 * table.n)
