"""Static calibration of a load measuring system: the 2 x 2 gain matrix from known loads.

Model: reference load L_j (N, x and y, applied to the journal) = G r_j + b, with r_j the
system's reading of load j (N, through the rig's channel gains), G the 2 x 2 gain matrix
(cross-axis terms included) and b the zero-load offset. Each axis is an ordinary least-squares
fit of three parameters; the residuals give one pooled variance s^2 (both axes, 2 (n - 3)
degrees of freedom) and cov = s^2 (A^T A)^-1. The reference's stated relative standard
uncertainty u_ref scales every load alike, so it adds (u_ref G_ab)^2 to each entry's variance.

Expanded uncertainty of a fitted quantity (:func:`expanded`): U = k u, k the Student-t coverage
factor (reduction.statistics.coverage_factor, 95.45 %) at the Welch-Satterthwaite effective degrees
of freedom of u: the residuals' part has the fit's dof (the gain matrix 2 (n - 3), a probe's line
and a lag's line n - 2), a reference's part is taken as exactly known. k = 2 would cover about 92 %
at 8 dof and 86 % at 3.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from reduction.errors import ReductionError
from reduction.statistics import coverage_factors, effective_dof
from rigunits import HZ


def expanded(u: np.ndarray, u_fit: np.ndarray, dof: int) -> tuple[np.ndarray, np.ndarray]:
    """(k, U) of standard uncertainties ``u`` (any shape) whose residuals' part ``u_fit`` has
    ``dof`` degrees of freedom and whose rest (a reference's) is known exactly: k of Student's t
    at the effective dof (reduction.statistics.effective_dof), U = k u."""
    k = coverage_factors(effective_dof(u, u_fit, dof))
    return k, k * np.asarray(u, dtype=float)


@dataclass(frozen=True)
class GainFit:
    """A load measuring system's calibration: reference = gain @ reading + offset (N)."""

    gain: np.ndarray  # (2, 2), 1
    gain_u: np.ndarray  # (2, 2) standard uncertainties of the entries, 1
    offset: np.ndarray  # (2,) N
    residual_rms: float  # N, the fit's residual standard deviation
    dof: int  # the residuals': 2 (n - 3)
    gain_u_fit: np.ndarray  # (2, 2) the residuals' part of gain_u (the reference's left out), 1

    def relative_gain_u(self) -> np.ndarray:
        """(2,) relative standard uncertainty of each axis' gain, cross term included (1)."""
        rel: np.ndarray = np.sqrt(np.sum(self.gain_u**2, axis=1)) / np.abs(np.diag(self.gain))
        return rel


def fit_gain_matrix(reference: np.ndarray, reading: np.ndarray, reference_u: float) -> GainFit:
    """The 2 x 2 gain matrix (and offset) mapping `reading` (n, 2) to `reference` (n, 2) loads (N)
    by least squares; `reference_u` the reference's relative standard uncertainty (1).
    ReductionError with fewer than 4 loads or loads that do not span both axes."""
    L, r = np.asarray(reference, dtype=float), np.asarray(reading, dtype=float)
    if L.shape != r.shape or L.ndim != 2 or L.shape[1] != 2:
        raise ReductionError(f"reference and reading must both be (n, 2), got {L.shape} and {r.shape}")
    n = L.shape[0]
    if n < 4:
        raise ReductionError(f"{n} loads cannot determine a 2 x 2 gain matrix and offset (at least 4)")
    if not (np.all(np.isfinite(L)) and np.all(np.isfinite(r))):
        raise ReductionError("loads and readings must be finite")
    if not np.isfinite(reference_u) or reference_u < 0:
        raise ReductionError(f"the reference's uncertainty must be finite and >= 0, got {reference_u}")
    A = np.column_stack([r, np.ones(n)])
    if np.linalg.matrix_rank(A) < 3:
        raise ReductionError("the loads do not span both axes: apply loads in x and in y")
    coef, *_ = np.linalg.lstsq(A, L, rcond=None)  # (3, 2): column a holds row a of G and b_a
    res = L - A @ coef
    dof = 2 * (n - 3)
    s2 = float(np.sum(res**2) / dof) if dof > 0 else 0.0
    inv = np.linalg.inv(A.T @ A)
    gain = coef[:2].T
    var_fit = s2 * np.diag(inv)[:2][None, :] * np.ones((2, 1))
    var = var_fit + (reference_u * gain) ** 2
    return GainFit(gain, np.sqrt(var), coef[2].copy(), float(np.sqrt(s2)), dof, np.sqrt(var_fit))


def correct_forces(gain: np.ndarray, fx: np.ndarray, fy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(fx, fy) of the journal from a system's readings (phasors or values, any shape) by its gain matrix."""
    g = np.asarray(gain)
    return g[0, 0] * fx + g[0, 1] * fy, g[1, 0] * fx + g[1, 1] * fy


def static_loads(magnitude: float) -> np.ndarray:
    """The default load set (n, 2), N: none, +-x, +-y and the two diagonals, each of `magnitude`."""
    d = magnitude / np.sqrt(2.0)
    return np.array(
        [[0, 0], [magnitude, 0], [-magnitude, 0], [0, magnitude], [0, -magnitude], [d, d], [d, -d]], dtype=float
    )


@dataclass(frozen=True)
class DelayFit:
    """A channel's lag behind the reference channels: phase(f) = phase + 2 pi f delay (rad, s),
    with standard uncertainties from the fit's residuals; ``phase`` in [-pi, pi)."""

    phase: float  # rad
    delay: float  # s
    phase_u: float
    delay_u: float
    residual_rms: float  # rad
    dof: int = 0  # the residuals': frequencies - 2

    @property
    def polarity(self) -> int:
        """-1 if the channel reads the reference inverted (``phase`` nearer +-pi than 0), else +1."""
        return polarity_and_lag(self.phase)[0]

    @property
    def lag(self) -> float:
        """The constant phase apart from the polarity (rad, in [-pi/2, pi/2])."""
        return polarity_and_lag(self.phase)[1]


def wrap_phase(phase: float) -> float:
    """``phase`` (rad) wrapped into [-pi, pi) (one already there unchanged)."""
    if -np.pi <= phase < np.pi:
        return float(phase)
    wrapped = float((phase + np.pi) % (2 * np.pi) - np.pi)
    return wrapped if -np.pi <= wrapped < np.pi else -np.pi


def polarity_and_lag(phase: float) -> tuple[int, float]:
    """(polarity, lag) of a channel's constant phase (rad) behind the reference: a phase nearer
    +-pi than 0 is a reading inverted against the reference (polarity -1: a sign, the gain's,
    never a lag), the rest the lag (rad, in [-pi/2, pi/2])."""
    p = wrap_phase(phase)
    turns = round(p / np.pi)  # -1, 0 or 1
    return (-1 if turns else 1), p - turns * np.pi


def fit_delay(frequencies: np.ndarray, lag: np.ndarray) -> DelayFit:
    """Least-squares line through a channel's measured lag (rad, unwrapped along ascending
    frequency, in any order given) behind the reference at `frequencies` (Hz): lag = phase + 2 pi f delay, the phase wrapped into
    [-pi, pi). ReductionError with fewer than 3 distinct frequencies or a lag not finite."""
    f, y = np.asarray(frequencies, dtype=float), np.asarray(lag, dtype=float)
    if f.shape != y.shape or f.ndim != 1 or len(np.unique(f)) < 3:
        raise ReductionError("a phase and a delay need the lag at 3 or more distinct frequencies")
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(y))):
        raise ReductionError("the frequencies and lags must be finite (a channel that read no reference?)")
    order = np.argsort(f, kind="stable")  # unwrapped along frequency, whatever order the speeds were run in
    f, y = f[order], np.unwrap(y[order])
    A = np.column_stack([np.ones_like(f), HZ * f])
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    res = y - A @ coef
    s2 = float(np.sum(res**2) / (len(f) - 2))
    cov = s2 * np.linalg.inv(A.T @ A)
    return DelayFit(
        wrap_phase(float(coef[0])),
        float(coef[1]),
        float(np.sqrt(cov[0, 0])),
        float(np.sqrt(cov[1, 1])),
        float(np.sqrt(s2)),
        len(f) - 2,
    )


def correct_lag(values: np.ndarray, orbit: np.ndarray, phase: float, delay: float) -> np.ndarray:
    """Phasors of a channel that lags by phase + |Omega| delay (rad, s), brought in step with the
    reference channels; `orbit` (rad/s) broadcast against `values`."""
    corrected: np.ndarray = np.asarray(values) * np.exp(1j * (phase + np.abs(np.asarray(orbit)) * delay))
    return corrected


@dataclass(frozen=True)
class ProbeFit:
    """A displacement probe's calibration: step = gain * reading + offset (m), the gain's standard
    uncertainty (residuals and the reference's) and the residuals' part of it alone, and its
    linearity: the largest deviation of the readings from the line, relative to the span of the
    steps (1)."""

    gain: float
    gain_u: float
    offset: float
    linearity: float
    residual_rms: float  # m
    gain_u_fit: float  # the residuals' part of gain_u (the reference's left out)
    dof: int = 0  # the residuals': steps - 2


def fit_probe(steps: np.ndarray, reading: np.ndarray, reference_u: float) -> ProbeFit:
    """The line through a probe's `reading` (n,) of known `steps` (n,, m); `reference_u` the
    steps' relative standard uncertainty. ReductionError with fewer than 3 distinct steps."""
    d, r = np.asarray(steps, dtype=float), np.asarray(reading, dtype=float)
    if d.shape != r.shape or d.ndim != 1 or len(np.unique(d)) < 3:
        raise ReductionError("a probe's gain and linearity need 3 or more distinct steps")
    A = np.column_stack([r, np.ones_like(r)])
    coef, *_ = np.linalg.lstsq(A, d, rcond=None)
    res = d - A @ coef
    s2 = float(np.sum(res**2) / (len(d) - 2))
    var_fit = s2 * np.linalg.inv(A.T @ A)[0, 0]
    var = var_fit + (reference_u * coef[0]) ** 2
    return ProbeFit(
        float(coef[0]),
        float(np.sqrt(var)),
        float(coef[1]),
        float(np.max(np.abs(res)) / np.ptp(d)),
        float(np.sqrt(s2)),
        float(np.sqrt(var_fit)),
        len(d) - 2,
    )
