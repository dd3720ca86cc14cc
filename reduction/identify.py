"""Identification of rotordynamic coefficients from an orbit table.

``identify(table, model, freq_dep, method, solver)`` builds the impedance regression
(:mod:`reduction.impedance`: 4 real equations per orbit frequency, any orbit shape), checks
identifiability BEFORE solving (:mod:`reduction.identifiability`: refuses with the named
confounded combinations), solves it in column-scaled coordinates and reports diagnostics.

Methods
-------
ols : ordinary least squares (qr | svd | lu solver, agreeing to rounding).
wls : weighted least squares. Weights: the inverse effective variances of the equations from
      the table's u_* columns (:func:`reduction.noise.equation_variances`, force noise plus
      displacement noise through Z, Z from a first ols pass then the wls one); without u_*
      the coherences (:func:`reduction.noise.coherence_variances`, floored at 1/n_records).
tls : total least squares for noisy displacements, see :func:`reduction.regression.structured_tls`.
      Noise of every phasor from the u_* columns; without them the noise ratio
      sigma_f / sigma_d (N/m) is rms|f| / rms|d| (equal relative noise on displacement and
      force phasors) unless ``tls_ratio`` is given (either kept as ``Identification.tls_ratio``).
iv  : instrumental variables (two-stage least squares). Instruments: the regression built
      from the ideal circular orbit the rig imposes - one circle of common radius and trigger
      phase per whirl direction, fitted (complex mean of the dominant whirl component) to the
      OTHER rows of that direction (leave-one-out), so a row's instrument is independent of
      that row's measurement noise. Requires near-circular orbits of constant radius and
      trigger phase (the eccentric-spindle rig at one operating point), at least two rows per
      whirl direction.

Plain least squares is biased towards zero (attenuated) when the displacements carry noise;
tls and iv remove that bias (tested by Monte Carlo in tests/reduction).

Reported ``condition_number``: 2-norm condition number of the column-scaled regression
matrix (unit column norms; row-weighted for wls) - the amplification of relative data errors
into relative coefficient errors, independent of the coefficients' units.
``covariance`` / ``std_errors``: with u_* columns from the stated uncertainties (absolute,
see :mod:`reduction.statistics`), otherwise s^2 (A^T A)^-1 with s^2 = residual sum of squares
/ (4n - p) (estimator-specific forms for wls, tls, iv); None when 4n == p and the noise is
unknown. ``confidence_95``: with u_* the normal quantile 1.96 (the covariance is known, so
also at 4n - p = 0), else Student's t with 4n - p degrees of freedom (``interval``).
``not_determined``: the coefficients whose statistical expanded uncertainty U = k x std error
exceeds their magnitude (k of reduction.statistics.coverage_factor: 2 with u_*; the sweep's rule).
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np

from reduction import regression as reg
from reduction import statistics as st
from reduction.arrays import FloatArray
from reduction.attenuation import attenuation_bias, attenuation_warning
from reduction.equation_noise import effective_variances, fit_chi2, variances
from reduction.errors import IdentifiabilityError, IdentificationError, ReductionError
from reduction.excitation import SignalDesign, displacement_noise, signal_design, signal_warning
from reduction.identifiability import analyse, check_signal, no_exponent
from reduction.identify_result import identification_of
from reduction.impedance import impedance, impedance_basis, regression, regression_rows, regressors
from reduction.instruments import circle_instruments, circle_orbits
from reduction.methods import METHODS, Method, Solver
from reduction.models import AUTO_EXPONENTS, ModelSpec, check_model, model_spec, parse_freq_dep, power_spec
from reduction.noise import equation_variances
from reduction.rank import RANK_RTOL
from reduction.result import Identification
from reduction.selection import Selection, selection
from reduction.table import OrbitTable

__all__ = ["METHODS", "Method", "Identification", "identify", "check_options", "circle_orbits"]


def identify(
    table: OrbitTable,
    model: str = "kcd11",
    freq_dep: str = "none",
    method: Method | str = Method.OLS,
    solver: Solver | str = Solver.QR,
    *,
    rank_rtol: float = RANK_RTOL,
    tls_ratio: float | None = None,
) -> Identification:
    """Identify ``model`` (kc7 | kc8 | kcd11 | kcd12) with ``freq_dep`` (none | power:M |
    power:m,n,p | power:auto | poly:R) from ``table`` by ``method`` (ols | wls | tls | iv)
    using ``solver`` (qr | svd | lu) for the linear least-squares steps.

    Raises IdentifiabilityError (too few frequencies, rank-deficient regression: the message
    names the confounded combinations and what data would separate them), IdentificationError
    (e.g. wls without coherences) or ReductionError (unknown option).
    """
    check_options(model, freq_dep, method)
    method = Method(method)
    solver = reg.solver_of(solver)
    if not isinstance(table, OrbitTable):
        raise ReductionError("identify needs an OrbitTable")
    fd = parse_freq_dep(freq_dep)
    if not fd.auto:
        return _identify(table, model_spec(model, fd), method, solver, rank_rtol, tls_ratio)
    results, refused = {}, {}
    for m in AUTO_EXPONENTS:
        spec = power_spec(model, m)
        try:
            results[m] = _identify(table, spec, method, solver, rank_rtol, tls_ratio)
        except IdentifiabilityError as err:
            if table.n < spec.min_frequencies:
                raise
            refused[m] = err
    if not results:
        raise no_exponent(model, refused, "this table")
    best_m = min(results, key=lambda m: results[m].cost)
    best = results[best_m]
    best.exponent = best_m
    best.freq_dep = "power:auto"
    best.skipped = {m: str(err) for m, err in refused.items()}
    if len(results) > 1:
        best.selection = _selection(table, model, method, best, tuple(results))
    best.notes.append(
        f"power:auto chose the exponent M = {best_m} (least residual of M in "
        + ", ".join(str(m) for m in results)
        + ")"
        + (f"; not identifiable: M = {', '.join(str(m) for m in refused)}" if refused else "")
    )
    return best


def check_options(model: str, freq_dep: str = "none", method: Method | str = Method.OLS) -> None:
    """Raise ReductionError for an unknown model, frequency dependence or method, as
    :func:`identify` does, without a table: the one check of these options and its wording,
    for callers that check usage before reading any data."""
    check_model(model)
    parse_freq_dep(freq_dep)
    if method not in METHODS:
        raise ReductionError(f"unknown method {method!r}: use one of {', '.join(METHODS)}")


def _selection(
    table: OrbitTable, model: str, method: str, chosen: Identification, exponents: tuple[int, ...]
) -> Selection:
    """power:auto's choice among ``exponents`` as a reduction.selection.Selection: the
    candidates' regressions weighted as the chosen fit weighs its equations, side by side, taken
    over blocks of rows as their triangular factor (a long table's are never whole in memory)."""
    specs = [model_spec(model), *(power_spec(model, m) for m in exponents)]
    w = 1.0 / np.sqrt(variances(chosen.spec, table, chosen.theta, np.zeros(4 * table.n), method))
    rows = reg.CHUNK_ROWS // 4

    def blocks() -> Iterator[FloatArray]:
        for s in range(0, table.n, rows):
            at = slice(s, s + rows)
            columns = [regression_rows(spec, table.orbit[at], table.x[at], table.y[at]) for spec in specs]
            yield np.hstack(columns) * w[4 * s : 4 * (s + rows), None]

    widths = [spec.n_coefficients for spec in specs]
    # Householder (0 equations: no Cholesky QR): the candidates repeat the constant's columns
    R = reg.triangular_blocks(blocks, 0, sum(widths))
    parts = np.split(R, np.cumsum(widths)[:-1], axis=1)
    return selection(parts[0], dict(zip(exponents, parts[1:])), np.ones(R.shape[0]), 4 * table.n)


def _identify(
    table: OrbitTable, spec: ModelSpec, method: Method, solver: Solver, rank_rtol: float, tls_ratio: float | None
) -> Identification:
    A, b = _regression(spec, table)
    u = table.u
    known = u is not None
    rank = analyse(spec, table, A, rank_rtol)  # raises when not identifiable
    c = rank.scale
    A_s = A
    A_s /= c  # in place (a long table has room for one regression matrix): the column-scaled A
    x0 = reg.lstsq(A_s, b, solver)  # the ols solution (scaled), the first pass of every method
    signal = _signal(spec, table, A_s, b, c, x0, rank_rtol)  # raises when not identifiable on signal
    var = variances(spec, table, x0 / c, b, method)
    if method == Method.WLS:  # the weighted regression's own scaling and conditioning
        rank = analyse(spec, table, A_s * (c / np.sqrt(var)[:, None]), rank_rtol)
        A_s *= c / rank.scale
        c = rank.scale
    P = None  # the estimator's linear map b -> scaled coefficients (iv)
    if method == Method.OLS:
        est = reg.ols(A_s, b, solver, rank.unscaled_covariance(), x0)
    elif method == Method.WLS:
        est = reg.wls(A_s, b, 1.0 / var, solver, rank.unscaled_covariance())
        if u is not None:  # second pass: effective variances at the wls coefficients
            est = reg.wls(A_s, b, 1.0 / effective_variances(spec, u, table, est.x / c), solver)
    elif method == Method.IV:
        Zi = circle_instruments(spec, table, rank_rtol) / c
        est = reg.iv(A_s, Zi, b, solver)
        if known:
            Qz, _ = np.linalg.qr(Zi)
            P = st.pseudo_inverse(Qz @ (Qz.T @ A_s))
    else:
        est = _tls(spec, table, A_s, b, c, solver, tls_ratio)
    theta = est.x / c
    Z = impedance(spec, theta, table.orbit)  # at the estimate: effective variances and the fit
    chi2 = None if u is None else fit_chi2(spec, u, table, A_s, b, c, var, method, est)
    cov_s: FloatArray | None
    if u is not None:
        var = equation_variances(u, Z)
        if method == Method.OLS and est.unscaled is not None:  # ols: always (reduction.regression._finish)
            cov_s = st.sandwich_rows(A_s, var, est.unscaled)
        else:
            cov_s = st.sandwich(P, var) if P is not None else est.unscaled
    else:
        cov_s = est.cov
    ident = identification_of(spec, table, method, solver, est, theta, c, cov_s, rank, chi2, Z)
    ident.tls_ratio = tls_noise_ratio(table, tls_ratio) if method == Method.TLS and u is None else None
    weak = signal_warning(signal)
    if weak:
        ident.warnings.insert(0, weak)
    if u is not None and method in (Method.OLS, Method.WLS):
        unscaled = rank.unscaled_covariance() if method == Method.OLS else est.unscaled
        if unscaled is not None and ident.covariance is not None:  # both are, with u_* and ols or wls
            weights = None if method == Method.OLS else 1.0 / effective_variances(spec, u, table, theta)
            bias = attenuation_bias(spec, table, theta, c, unscaled, weights)  # wls: the weights it fitted with
            std = np.sqrt(np.clip(np.diag(ident.covariance), 0, None))
            eiv = attenuation_warning(spec, method, bias, std)
            if eiv:
                ident.warnings.append(eiv)
    return ident


def _signal(
    spec: ModelSpec, table: OrbitTable, A_s: FloatArray, b: FloatArray, c: FloatArray, x0: FloatArray, rtol: float
) -> SignalDesign:
    """The design without the displacement directions not clear of their noise (u_x, u_y,
    else the residual of a first ols fit); raises IdentifiabilityError when it cannot
    identify ``spec``."""
    if table.u is not None:
        noise = displacement_noise(table)
    else:
        theta0 = x0 / c
        noise = displacement_noise(
            table, b - A_s @ x0, impedance(spec, theta0, table.orbit), 4 * table.n - spec.n_coefficients
        )
    design = signal_design(table, noise)
    check_signal(spec, table, design, rtol)
    return design


def _regression(spec: ModelSpec, table: OrbitTable) -> tuple[FloatArray, FloatArray]:
    with np.errstate(over="ignore", invalid="ignore"):
        A, b = regression(spec, table.orbit, table.x, table.y, table.fx, table.fy)
        finite = (
            np.all(np.isfinite(A))
            and np.all(np.isfinite(b))
            and np.isfinite(np.linalg.norm(A))
            and np.isfinite(np.linalg.norm(b))
        )
    if not finite:
        raise IdentificationError(
            f"{spec.model} with freq-dep {spec.freq_dep.text}: the regression exceeds the floating-point "
            "range (Omega^r times the displacements, or the forces, are too large); check the table's "
            "units (orbit_hz in Hz, phasors in m and N)"
        )
    return A, b


def _tls(
    spec: ModelSpec,
    table: OrbitTable,
    A_s: FloatArray,
    b: FloatArray,
    c: FloatArray,
    solver: Solver,
    ratio: float | None,
) -> reg.Estimate:
    var_f, var_d = tls_variances(table, ratio)
    x0 = reg.ols(A_s, b, solver).x
    G = regressors(spec, table.orbit, table.x, table.y) / c
    E = impedance_basis(spec, table.orbit) / c[None, :, None, None]
    return reg.structured_tls(G, np.stack([table.fx, table.fy], axis=1), E, var_f, var_d, x0)


def tls_variances(table: OrbitTable, ratio: float | None = None) -> tuple[FloatArray, FloatArray]:
    """(var_f (n, 2) N^2, var_d (n, 2) m^2) the tls fit weighs ``table``'s phasors by: the u_*
    columns squared (var_f floored), else 1 m^2 and ``ratio``^2 (default rms|f| / rms|d|, N/m)."""
    if table.u is not None:
        var_d, var_f = table.u[:, :2] ** 2, table.u[:, 2:] ** 2
        f = np.stack([table.fx, table.fy], axis=1)
        tiny = 1e-12 * max(float(np.max(var_f)), float(np.max(var_d)) * float(np.max(np.abs(f)) ** 2 + 1))
        return np.maximum(var_f, tiny), var_d
    ratio = tls_noise_ratio(table, ratio)
    return np.full((table.n, 2), ratio**2), np.ones((table.n, 2))


def tls_noise_ratio(table: OrbitTable, ratio: float | None = None) -> float:
    """The noise ratio sigma_f / sigma_d (N/m) a tls fit without u_* weighs ``table``'s phasors by:
    ``ratio`` when given, else rms|f| / rms|d| (equal relative noise on forces and displacements)."""
    if ratio is None:
        d, f = np.stack([table.x, table.y], axis=1), np.stack([table.fx, table.fy], axis=1)
        ratio = float(np.sqrt(np.mean(np.abs(f) ** 2) / np.mean(np.abs(d) ** 2)))
    if not ratio > 0 or not math.isfinite(ratio):
        raise IdentificationError(f"tls: noise ratio must be finite and > 0 N/m, got {ratio!r}")
    return ratio
