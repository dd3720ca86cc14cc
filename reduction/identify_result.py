"""The Identification of a solved regression: coefficients in SI with their standard errors
and 95 % intervals (normal with u_*, else Student's t with 4n - p dof), chi2's verdict, AIC and
BIC, the ill-conditioning warning, the coefficients not determined (U = k x std error above
their magnitude) and the fit's residuals at the table's orbit frequencies.
"""

from __future__ import annotations

import numpy as np

from reduction import regression as reg
from reduction import statistics as st
from reduction.arrays import ComplexArray, FloatArray
from reduction.conditioning import ill_conditioning
from reduction.diagnostics import fit_errors, residual_rms
from reduction.impedance import forces
from reduction.methods import Method
from reduction.models import ModelSpec
from reduction.rank import Rank
from reduction.result import Identification
from reduction.table import OrbitTable

#: ols and iv with u_*: their chi2 (and so AIC and BIC) is the wls solution's (reduction.statistics)
_AT_WLS = "; chi2, AIC and BIC at the wls solution (the coefficients and their covariance this method's own)"


def identification_of(
    spec: ModelSpec,
    table: OrbitTable,
    method: str,
    solver: str,
    est: reg.Estimate,
    theta: FloatArray,
    c: FloatArray,
    cov_s: FloatArray | None,
    rank: Rank,
    chi2: float | None,
    Z: ComplexArray,
) -> Identification:
    known = chi2 is not None
    p, dof = spec.n_coefficients, 4 * table.n - spec.n_coefficients
    cov = None if cov_s is None else cov_s / np.outer(c, c)
    std = np.full(p, np.nan) if cov is None else np.sqrt(np.clip(np.diag(cov), 0, None))
    interval = st.Interval.NORMAL if known else st.Interval.STUDENT_T
    ci = st.intervals(theta, std, dof, interval=interval)
    notes, warnings = list(spec.notes), []
    p_value: float | None = None
    if chi2 is not None:
        p_value = st.chi2_p_value(chi2, dof)
        notes.append(
            "covariance, weights and chi2 from the table's u_x, u_y, u_fx, u_fy "
            "(force noise plus displacement noise through Z)" + (_AT_WLS if method in (Method.OLS, Method.IV) else "")
        )
        bad = st.chi2_warning(chi2, dof, p_value)
        if bad:
            warnings.append(bad)
    elif method == Method.WLS:
        notes.append(
            "wls weights from the coherences (no u_* columns): per-record noise ratio "
            "(1 - gamma^2)/gamma^2 floored at 1/n_records"
        )
    aic, bic = st.information_criteria(chi2 if chi2 is not None else est.rss, 4 * table.n, p, known)
    ill = ill_conditioning(spec, table, rank)
    if ill:
        warnings.append(ill)
    ident = Identification(
        model=spec.model,
        freq_dep=spec.freq_dep.text,
        method=str(method),
        n_coefficients=p,
        min_frequencies=spec.min_frequencies,
        n_frequencies=table.n,
        coefficients={k: float(v) for k, v in spec.expand(theta).items()},
        std_errors={k: (None if not np.isfinite(v) else float(v)) for k, v in spec.expand(std).items()},
        condition_number=rank.condition_number,
        residual_rms=0.0,
        fit=[],
        solver=str(solver),
        spec=spec,
        theta=theta,
        cost=est.rss,
        free=spec.names,
        covariance=cov,
        dof=dof,
        confidence_95={
            k: (None if not np.all(np.isfinite(v)) else (float(v[0]), float(v[1])))
            for k, v in spec.expand(list(ci)).items()
        },
        chi2=chi2,
        p_value=p_value,
        aic=aic,
        bic=bic,
        notes=notes,
        warnings=warnings,
        known_noise=known,
        interval=interval,
    )
    ident.not_determined = st.not_determined(
        ident.coefficients, st.statistical_expanded(spec.expand(std), interval, dof)
    )
    fx_rep, fy_rep = forces(Z, table.x, table.y)  # ident.reproduce(table), Z computed once
    ident.residual_rms = residual_rms(table.fx, table.fy, fx_rep, fy_rep)
    ident.fit = fit_errors(table.orbit, table.fx, table.fy, fx_rep, fy_rep)
    return ident
