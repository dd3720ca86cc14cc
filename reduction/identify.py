"""Identification of rotordynamic coefficients from an orbit table.

``identify(table, model, freq_dep, method, solver)`` builds the impedance regression
(:mod:`reduction.impedance`: 4 real equations per orbit frequency, any orbit shape), checks
identifiability BEFORE solving (:mod:`reduction.identifiability`: refuses with the named
confounded combinations), solves it in column-scaled coordinates and reports diagnostics.

Methods
-------
ols : ordinary least squares (qr | svd | lu solver, agreeing to rounding).
wls : weighted least squares with coherence weights (the table's gamma2 columns),
      var(f) ~ |f|^2 (1 - gamma^2) / gamma^2, see :func:`reduction.coherence.coherence_weights`.
tls : total least squares for noisy displacements, see :func:`reduction.regression.structured_tls`.
      Noise ratio sigma_f / sigma_d (N/m) defaults to rms|f| / rms|d| (equal relative noise on
      displacement and force phasors, the usual normalisation of TLS); pass ``tls_ratio``
      when the noise levels are known.
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
``std_errors``: one standard deviation from the regression covariance s^2 (A^T A)^-1 with
s^2 = residual sum of squares / (4n - p) (estimator-specific forms for wls, tls, iv); None
when 4n == p (no degrees of freedom).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from reduction import regression as reg
from reduction.coherence import coherence_weights
from reduction.diagnostics import fit_errors, residual_rms
from reduction.errors import IdentificationError, IdentifiabilityError, ReductionError
from reduction.identifiability import RANK_RTOL, analyse, numerical_rank
from reduction.impedance import forces, impedance, impedance_basis, real_rows, regression, regressors
from reduction.models import AUTO_EXPONENTS, ModelSpec, model_spec, parse_freq_dep, power_spec
from reduction.table import OrbitTable

METHODS = ("ols", "wls", "tls", "iv")
IV_MAX_MISFIT = 0.3  # rms |d - circle| / rms |d| above which the circle instruments are refused


@dataclass
class Identification:
    """Result of :func:`identify` (coefficients in SI: N/m, N s/m, kg, Omega in rad/s).

    ``coefficients`` / ``std_errors`` use the spec's keys (``Kxx``, ``Kxx_1``, ...; a
    symmetric pair appears under both keys). ``exponent`` is the M chosen by power:auto.
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
    fit: list[dict]
    exponent: int | None = None
    solver: str = "qr"
    spec: ModelSpec | None = field(default=None, repr=False)
    theta: np.ndarray | None = field(default=None, repr=False)  # free coefficients, column order
    cost: float = field(default=float("nan"), repr=False)  # the estimator's minimised objective
    skipped: dict[int, str] = field(default_factory=dict, repr=False)  # power:auto: M -> reason

    def to_dict(self) -> dict:
        """The spec's JSON object (``exponent`` added for power:auto); NaN/inf -> None."""
        d = {
            "model": self.model, "freq_dep": self.freq_dep, "method": self.method,
            "n_coefficients": self.n_coefficients, "min_frequencies": self.min_frequencies,
            "n_frequencies": self.n_frequencies,
            "coefficients": {k: _num(v) for k, v in self.coefficients.items()},
            "std_errors": {k: _num(v) for k, v in self.std_errors.items()},
            "condition_number": _num(self.condition_number),
            "residual_rms": _num(self.residual_rms),
            "fit": [{k: _num(v) for k, v in row.items()} for row in self.fit],
        }
        if self.exponent is not None:
            d["exponent"] = self.exponent
        return d

    def matrices(self, orbit: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(K, C, D) 2x2 at orbit frequency Omega (rad/s), summed over their orders
        (K(Omega) = sum_r Omega^r K^(r)); D is zeros for a model without D."""
        w = float(orbit)
        out = {m: np.zeros((2, 2)) for m in "KCD"}
        for t, v in zip(self.spec.terms, self.theta):
            for i, j in t.entries:
                out[t.matrix][i, j] += v * w**t.order
        return out["K"], out["C"], out["D"]

    def impedance(self, orbit) -> np.ndarray:
        """Z(Omega) = K + i Omega C - Omega^2 D, shape (n, 2, 2), N/m."""
        return impedance(self.spec, self.theta, orbit)

    def reproduce(self, table: OrbitTable) -> tuple[np.ndarray, np.ndarray]:
        """Reproduced force phasors (fx, fy), N, f = -Z(Omega) d from the table's displacements."""
        return forces(self.impedance(table.orbit), table.x, table.y)


def _num(v):
    if v is None:
        return None
    v = float(v)
    return v if math.isfinite(v) else None


def identify(table: OrbitTable, model: str = "kcd11", freq_dep: str = "none", method: str = "ols",
             solver: str = "qr", *, rank_rtol: float = RANK_RTOL,
             tls_ratio: float | None = None) -> Identification:
    """Identify ``model`` (kc7 | kc8 | kcd11 | kcd12) with ``freq_dep`` (none | power:M |
    power:m,n,p | power:auto | poly:R) from ``table`` by ``method`` (ols | wls | tls | iv)
    using ``solver`` (qr | svd | lu) for the linear least-squares steps.

    Raises IdentifiabilityError (too few frequencies, rank-deficient regression: the message
    names the confounded combinations and what data would separate them), IdentificationError
    (e.g. wls without coherences) or ReductionError (unknown option).
    """
    if method not in METHODS:
        raise ReductionError(f"unknown method {method!r}: use one of {', '.join(METHODS)}")
    if solver not in reg.SOLVERS:
        raise ReductionError(f"unknown solver {solver!r}: use one of {', '.join(reg.SOLVERS)}")
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
        raise IdentifiabilityError(
            f"{model} with freq-dep power:auto: no exponent M in "
            f"{AUTO_EXPONENTS[0]}..{AUTO_EXPONENTS[-1]} is identifiable from this table.\n\n"
            + "\n\n".join(f"power:{m}: {err}" for m, err in refused.items()),
            [f"power:{m}: {c}" for m, err in refused.items() for c in err.combinations])
    best_m = min(results, key=lambda m: results[m].cost)
    best = results[best_m]
    best.exponent = best_m
    best.freq_dep = "power:auto"
    best.skipped = {m: str(err) for m, err in refused.items()}
    return best


def _identify(table: OrbitTable, spec: ModelSpec, method: str, solver: str, rank_rtol: float,
              tls_ratio: float | None) -> Identification:
    with np.errstate(over="ignore", invalid="ignore"):
        A, b = regression(spec, table.orbit, table.x, table.y, table.fx, table.fy)
        finite = (np.all(np.isfinite(A)) and np.all(np.isfinite(b))
                  and np.isfinite(np.linalg.norm(A)) and np.isfinite(np.linalg.norm(b)))
    if not finite:
        raise IdentificationError(
            f"{spec.model} with freq-dep {spec.freq_dep.text}: the regression exceeds the floating-point "
            "range (Omega^r times the displacements, or the forces, are too large); check the table's "
            "units (orbit_hz in Hz, phasors in m and N)")
    weights = None
    if method == "wls":
        if table.gamma2 is None:
            raise IdentificationError(
                "--method wls needs coherence values: the table has no gamma2_xfx, gamma2_yfx, "
                "gamma2_xfy, gamma2_yfy columns")
        weights = coherence_weights(table.gamma2, table.fx, table.fy)
        A_eff = A * np.sqrt(weights)[:, None]
    else:
        A_eff = A
    rank = analyse(spec, table, A_eff, rank_rtol)  # raises when not identifiable
    c = rank.scale
    A_s = A / c
    if method == "ols":
        est = reg.ols(A_s, b, solver)
    elif method == "wls":
        est = reg.wls(A_s, b, weights, solver)
    elif method == "iv":
        est = reg.iv(A_s, _circle_instruments(spec, table, rank_rtol) / c, b, solver)
    else:
        est = _tls(spec, table, A_s, b, c, solver, tls_ratio)
    theta = est.x / c
    if est.cov is None:
        std = np.full(theta.shape, np.nan)
    else:
        std = np.sqrt(np.clip(np.diag(est.cov), 0, None)) / c
    ident = Identification(
        model=spec.model, freq_dep=spec.freq_dep.text, method=method,
        n_coefficients=spec.n_coefficients, min_frequencies=spec.min_frequencies,
        n_frequencies=table.n,
        coefficients={k: float(v) for k, v in spec.expand(theta).items()},
        std_errors={k: (None if not np.isfinite(v) else float(v)) for k, v in spec.expand(std).items()},
        condition_number=rank.condition_number, residual_rms=0.0, fit=[], solver=solver,
        spec=spec, theta=theta, cost=est.rss)
    fx_rep, fy_rep = ident.reproduce(table)
    ident.residual_rms = residual_rms(table.fx, table.fy, fx_rep, fy_rep)
    ident.fit = fit_errors(table.orbit, table.fx, table.fy, fx_rep, fy_rep)
    return ident


def _tls(spec, table, A_s, b, c, solver, ratio):
    d = np.stack([table.x, table.y], axis=1)
    f = np.stack([table.fx, table.fy], axis=1)
    if ratio is None:
        ratio = float(np.sqrt(np.mean(np.abs(f) ** 2) / np.mean(np.abs(d) ** 2)))
    if not ratio > 0 or not math.isfinite(ratio):
        raise IdentificationError(f"tls: noise ratio must be finite and > 0 N/m, got {ratio!r}")
    x0 = reg.ols(A_s, b, solver).x
    G = regressors(spec, table.orbit, table.x, table.y) / c
    E = impedance_basis(spec, table.orbit) / c[None, :, None, None]
    return reg.structured_tls(G, f, E, ratio, x0)


def circle_orbits(table: OrbitTable) -> tuple[np.ndarray, np.ndarray]:
    """The iv instruments' orbits: per row, the circle of the row's dominant whirl direction
    whose complex radius is the mean of that direction's dominant component over the OTHER
    rows of the same direction (leave-one-out). Returns (x_hat, y_hat), m."""
    a_f, a_b = table.whirl_components()
    forward = np.abs(a_f) >= np.abs(a_b)
    a = np.where(forward, a_f, a_b)
    x_hat = np.empty(table.n, dtype=complex)
    for direction in (True, False):
        rows = np.flatnonzero(forward == direction)
        if rows.size == 1:
            raise IdentificationError(
                "iv needs at least two orbits of each whirl direction present "
                "(the instruments are leave-one-out circles)")
        if rows.size:
            x_hat[rows] = (np.sum(a[rows]) - a[rows]) / (rows.size - 1)
    y_hat = np.where(forward, -1j, 1j) * x_hat
    return x_hat, y_hat


def _circle_instruments(spec: ModelSpec, table: OrbitTable, rank_rtol: float) -> np.ndarray:
    x_hat, y_hat = circle_orbits(table)
    misfit = np.sqrt(np.mean(np.abs(table.x - x_hat) ** 2 + np.abs(table.y - y_hat) ** 2)
                     / np.mean(np.abs(table.x) ** 2 + np.abs(table.y) ** 2))
    if misfit > IV_MAX_MISFIT:
        raise IdentificationError(
            f"iv: the orbits are not circles of common radius and trigger phase (misfit {misfit:.0%} "
            f"> {IV_MAX_MISFIT:.0%}), so the circle instruments do not fit this table; use --method tls")
    Z = real_rows(regressors(spec, table.orbit, x_hat, y_hat))
    if numerical_rank(Z, rank_rtol).deficiency:
        raise IdentificationError(
            "iv: the circular-orbit instruments cannot separate this model's coefficients "
            "(e.g. a single whirl direction); use --method tls")
    return Z
