"""Noise of the averaged phasors: per-row uncertainties and the regression's weights.

An orbit table row holds phasors averaged over n revolutions (records). Their standard
uncertainty u = sqrt(E|error|^2) of the complex value (m or N) is estimated from the scatter
of the per-revolution phasors, :func:`phasor_uncertainty`. For circular complex noise each
of Re and Im carries the variance u^2 / 2.

In the regression f = -Z d the residual of one force equation carries the force noise and,
through Z, the displacement noise: var(r_x) = u_fx^2 + |Z_xx|^2 u_x^2 + |Z_xy|^2 u_y^2
(likewise r_y), :func:`equation_variances` - the effective variance that gives the weights
of ``wls``, the covariance and the chi2 when the table has u_* columns.

Without u_*, ``wls`` falls back on the coherences, :func:`coherence_variances`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
from numpy.typing import ArrayLike

from reduction.arrays import ComplexArray, FloatArray
from reduction.errors import ReductionError

SPIN_HARMONICS = (1, 2)  # spin harmonics whose leakage is fitted out of the scatter (runout, unbalance)
DEFAULT_RECORDS = 50  # revolutions per averaged phasor assumed when a table has no n_records


def phasor_uncertainty(record_phasors: ArrayLike, axis: int = 0) -> FloatArray:
    """Standard uncertainty of the mean of per-record (per-revolution) complex phasors:
    sqrt(sum_s |q_s - q_mean|^2 / (n - 1)) / sqrt(n), along ``axis`` (inf for n = 1).

    The one formula for u_x, u_y, u_fx, u_fy of the orbit table (same unit as the phasors).
    """
    q = np.asarray(record_phasors, dtype=complex)
    if q.ndim == 0 or q.shape[axis] < 1:
        raise ReductionError("phasor_uncertainty needs at least one record along axis")
    if not np.all(np.isfinite(q)):
        raise ReductionError("phasor_uncertainty: a record phasor is not finite (NaN or inf)")
    n = q.shape[axis]
    if n == 1:
        return np.full(np.delete(q.shape, axis % q.ndim), np.inf)
    dev = q - np.mean(q, axis=axis, keepdims=True)
    scatter2 = np.sum(np.abs(dev) ** 2, axis=axis) / (n - 1)
    u: FloatArray = np.sqrt(scatter2 / n)
    return u


def _advances(n: int, spin_turns: float, harmonics: Iterable[int]) -> tuple[float, ...]:
    """Phase advances per revolution (turns mod 1) of the mean (0) and of the spin tones
    h x spin, both signs, that n revolutions tell apart from the mean and from each other
    (two tones whose advances coincide mod one turn leak as one)."""
    advances = [0.0]
    for h in harmonics:
        for sign in (1, -1):
            a = (sign * h * spin_turns) % 1.0
            if all(min(abs(a - b), 1 - abs(a - b)) * n > 1.0 for b in advances):
                advances.append(a)
    return tuple(advances)


def _records(record_phasors: ArrayLike, spin_turns: float) -> ComplexArray:
    """The (n, ...) per-revolution phasors as complex, checked with ``spin_turns`` (omega/|Omega|):
    ReductionError for none, a non-finite phasor, or a spin_turns that is not finite and >= 0."""
    q = np.asarray(record_phasors, dtype=complex)
    if q.ndim == 0 or q.shape[0] < 1:
        raise ReductionError("per-revolution phasors: need at least one record")
    if not np.all(np.isfinite(q)):
        raise ReductionError("per-revolution phasors: a record phasor is not finite (NaN or inf)")
    if not (math.isfinite(spin_turns) and spin_turns >= 0):
        raise ReductionError(f"spin_turns (omega/|Omega|) must be finite and >= 0, got {spin_turns!r}")
    return q


def _positions(n: int, revolutions: ArrayLike | None) -> FloatArray:
    """(n,) revolution k of each record, counted from the first: the board's revolution
    numbers when given (a dropped revolution leaves a gap the tones still turn through)."""
    if revolutions is None:
        return np.arange(n, dtype=float)
    revs = np.asarray(revolutions, dtype=float)
    if revs.shape != (n,):
        raise ReductionError(f"revolution numbers: {revs.size} for {n} records")
    k: FloatArray = revs - revs[0]
    return k


def _tone_fit(
    record_phasors: ArrayLike, spin_turns: float, harmonics: Iterable[int], revolutions: ArrayLike | None = None
) -> tuple[ComplexArray, FloatArray]:
    """(residuals (n, C), white (C,)) of the least-squares fit of the mean and the resolvable
    spin tones."""
    q = _records(record_phasors, spin_turns)
    n = q.shape[0]
    X = np.exp(2j * np.pi * np.outer(_positions(n, revolutions), _advances(n, spin_turns, harmonics)))
    if n <= X.shape[1]:
        raise ReductionError(f"{n} revolutions cannot separate {X.shape[1] - 1} spin tones and the mean")
    coef, *_ = np.linalg.lstsq(X, q, rcond=None)
    resid: ComplexArray = q - X @ coef
    white: FloatArray = np.sqrt(np.sum(np.abs(resid) ** 2, axis=0) / (n - X.shape[1]))
    return resid, white


def revolution_noise(
    record_phasors: ArrayLike,
    spin_turns: float,
    revolutions: ArrayLike | None = None,
    harmonics: Iterable[int] = SPIN_HARMONICS,
) -> FloatArray:
    """Per-revolution standard uncertainty sqrt(E|e|^2) of each channel's phasor (same unit),
    with the spin-synchronous tones taken out of the scatter.

    record_phasors (n, C): one block's per-revolution phasors; ``revolutions`` (n,) their
    board revolution numbers (default consecutive). ``spin_turns`` = omega/|Omega|, the spin
    revolutions per orbit revolution. A tone at h x spin (runout, unbalance) leaks into
    revolution k's phasor as a e^{+-i 2 pi h spin_turns k}: it rotates from revolution to
    revolution, so it inflates the scatter, but its share of the mean shrinks like 1/n, not
    1/sqrt(n). Those exponentials (h in ``harmonics``, both signs) are fitted with the mean and
    removed; one whose advance per revolution is within 2 pi / n of a whole turn cannot be told
    from the mean over n revolutions and stays in (its leak into the mean is then in no
    uncertainty: docs/orbit-table.md gives the sizes near Omega/omega = 1). The residual scatter (degrees of freedom
    n - fitted columns) is the white part that averaging reduces as 1/sqrt(n).
    """
    return _tone_fit(record_phasors, spin_turns, harmonics, revolutions)[1]


def revolution_residuals(
    record_phasors: ArrayLike,
    spin_turns: float,
    revolutions: ArrayLike | None = None,
    harmonics: Iterable[int] = SPIN_HARMONICS,
) -> tuple[ComplexArray, FloatArray]:
    """((n, C) what each revolution's phasor differs from the mean and the fitted spin tones,
    (C,) their standard deviation :func:`revolution_noise`): a disturbed revolution stands out."""
    return _tone_fit(record_phasors, spin_turns, harmonics, revolutions)


def mean_uncertainty(
    record_phasors: ArrayLike,
    spin_turns: float,
    revolutions: ArrayLike | None = None,
    harmonics: Iterable[int] = SPIN_HARMONICS,
) -> FloatArray:
    """Standard uncertainty sqrt(E|mean - true|^2) of the plain mean of per-revolution phasors
    (n, C): the white part sigma^2 / n (:func:`revolution_noise`) plus what each fitted spin
    tone a e^{i phi k} leaves in the mean, |a|^2 |mean_k e^{i phi k}|^2 (the last row of
    :func:`prefix_mean_uncertainty`, so a block stores exactly what its stop rule checked).
    With too few revolutions to fit the tones, the scatter's :func:`phasor_uncertainty`."""
    q = _records(record_phasors, spin_turns)
    u = prefix_mean_uncertainty(q, spin_turns, start=q.shape[0] - 1, revolutions=revolutions, harmonics=harmonics)[0]
    return u if np.all(np.isfinite(u)) else phasor_uncertainty(q, axis=0)


def prefix_mean_uncertainty(
    record_phasors: ArrayLike,
    spin_turns: float,
    start: int = 0,
    revolutions: ArrayLike | None = None,
    harmonics: Iterable[int] = SPIN_HARMONICS,
) -> FloatArray:
    """(n - start, C): :func:`mean_uncertainty` of the first m records for every
    m = start+1..n at once (each m with the tones m revolutions resolve; inf where m is too
    small to fit them). Cumulative sums and batched small solves, one batch per tone set."""
    q = _records(record_phasors, spin_turns)
    n = q.shape[0]
    out = np.full((n - start,) + q.shape[1:], np.inf)
    counts = np.arange(start + 1, n + 1)
    sets = [_advances(int(m), spin_turns, harmonics) for m in counts]
    k = _positions(n, revolutions)
    s2 = np.cumsum(np.abs(q) ** 2, axis=0)  # (n, C)
    for adv in dict.fromkeys(sets):
        rows = np.array([i for i, a in enumerate(sets) if a == adv])
        m = counts[rows].astype(float)
        p = len(adv)
        rows, m = rows[m > p], m[m > p]
        if rows.size == 0:
            continue
        X = np.exp(2j * np.pi * np.outer(k, adv))  # (n, p)
        idx = rows + start  # the prefix of m records ends at record m - 1
        gram = np.cumsum(np.conj(X)[:, :, None] * X[:, None, :], axis=0)[idx]
        b = np.cumsum(np.conj(X)[:, :, None] * q[:, None, :], axis=0)[idx]
        try:
            coef = np.linalg.solve(gram, b)  # (r, p, C)
        except np.linalg.LinAlgError:  # tones too close over this prefix: leave it unjudged
            continue
        rss = np.maximum(s2[idx] - np.real(np.einsum("kpc,kpc->kc", np.conj(b), coef)), 0.0)
        leak = np.abs(np.cumsum(X[:, 1:], axis=0)[idx] / m[:, None]) ** 2
        tones = np.einsum("kj,kjc->kc", leak, np.abs(coef[:, 1:]) ** 2)
        out[rows] = np.sqrt(rss / (m - p)[:, None] / m[:, None] + tones)
    return out


def equation_variances(u: ArrayLike, Z: ComplexArray) -> FloatArray:
    """Variances of the 4n real equations (rows Re fx, Im fx, Re fy, Im fy per frequency).

    u (n, 4): standard uncertainties of x, y (m), fx, fy (N); Z (n, 2, 2) the impedance
    (N/m) at each row. Each real part carries half of the complex residual's E|r|^2.
    """
    uu = np.asarray(u, dtype=float)
    ud2 = uu[:, :2] ** 2  # (n, 2)
    uf2 = uu[:, 2:] ** 2
    var: FloatArray = uf2 + np.einsum("kij,kj->ki", np.abs(Z) ** 2, ud2)  # (n, 2) complex E|r|^2
    return np.repeat(var / 2, 2, axis=1).reshape(-1)


def coherence_variances(
    gamma2: ArrayLike, fx: ArrayLike, fy: ArrayLike, n_records: ArrayLike | None = None
) -> FloatArray:
    """Relative variances (any common scale) of the 4n real equations from the coherences.

    A force phasor of coherence gamma^2 with the motion has, per record, the noise-to-signal
    power rho = (1 - gamma^2) / gamma^2, and its average over n records the variance
    |f|^2 rho / n. For fx, gamma^2 is the mean of gamma2_xfx and gamma2_yfx (x and y are
    coherent with each other on a single-frequency orbit), likewise for fy.

    rho is floored at 1 / n: a coherence estimated from n records has a resolution (and a
    bias: its expectation is 1/n even for incoherent records) of order 1/n, so it cannot
    vouch for a smaller noise ratio. A row reading gamma^2 = 1.000 is therefore weighted like
    a row with rho = 1/n, not a million times heavier. n is ``DEFAULT_RECORDS`` when the table
    has no n_records.
    """
    g = np.asarray(gamma2, dtype=float)
    fxc, fyc = np.asarray(fx, dtype=complex), np.asarray(fy, dtype=complex)
    n = np.full(g.shape[0], float(DEFAULT_RECORDS)) if n_records is None else np.asarray(n_records, float)
    gx = np.clip((g[:, 0] + g[:, 1]) / 2, 1e-12, 1.0)
    gy = np.clip((g[:, 2] + g[:, 3]) / 2, 1e-12, 1.0)
    mag2 = np.stack([np.abs(fxc) ** 2, np.abs(fyc) ** 2], axis=1)
    mag2 = np.maximum(mag2, 1e-12 * max(float(np.mean(mag2)), np.finfo(float).tiny))
    rho = np.maximum(np.stack([(1 - gx) / gx, (1 - gy) / gy], axis=1), 1.0 / n[:, None])
    var: FloatArray = mag2 * rho / n[:, None]
    return np.repeat(var, 2, axis=1).reshape(-1)


class RunningScatter:
    """Running sums of a block's per-revolution phasors (C,), shifted by its first one
    (numerically stable): the standard uncertainty of their mean after each new
    revolution in O(channels) per revolution."""

    ref: np.ndarray | None
    s1: np.ndarray | None
    s2: np.ndarray | None

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.n = 0
        self.ref = self.s1 = self.s2 = None

    def _cumulative(self, records: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(the reference record, cumulative sums of the differences and of their squared
        magnitudes after each of ``records``)."""
        if self.ref is None or self.s1 is None or self.s2 is None:
            self.ref = records[0].copy()
            self.s1, self.s2 = np.zeros_like(self.ref), np.zeros(self.ref.shape)
        d = records - self.ref
        return self.ref, self.s1 + np.cumsum(d, axis=0), self.s2 + np.cumsum(d.real**2 + d.imag**2, axis=0)

    def first_met(self, records: np.ndarray, target: float, min_n: int) -> int:
        """Revolutions of ``records`` (R, C) after which every channel's uncertainty
        of the mean is at most ``target`` times the mean's magnitude, at a count of at
        least ``min_n`` (and 2); 0 if none."""
        ref, s1, s2 = self._cumulative(records)
        m = (self.n + 1 + np.arange(len(records), dtype=float))[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            var = (s2 - (s1.real**2 + s1.imag**2) / m) / (m - 1)
            u = np.sqrt(np.maximum(var, 0.0) / m)
            ok = np.all(u <= target * np.abs(ref + s1 / m), axis=1) & (m[:, 0] >= max(min_n, 2))
        hit = np.flatnonzero(ok)
        return int(hit[0]) + 1 if len(hit) else 0

    def add(self, records: np.ndarray) -> None:
        if not len(records):
            return
        _, s1, s2 = self._cumulative(records)
        self.s1, self.s2 = s1[-1], s2[-1]
        self.n += len(records)
