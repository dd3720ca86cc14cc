"""The slip of the slow roll's spin against its orbit spindle, from the runout itself.

At the slow roll both spindles turn at ratio 1, but they are driven independently and not
phase-locked: the spin turns 1 + s times per board revolution (s, the slip, a fraction). The
runout is locked to the spin angle, so its harmonic h in revolution k, phase to that revolution's
trigger, turns by h 2 pi s per revolution: q_k = R_h e^{i h 2 pi s k}. Averaged as it stands, the
mean loses |sinc|-like amplitude (0.1 % fast over 100 revolutions: 1x about 2 % low, 2x about 6 %).

`fit_slip` finds s from the revolutions' phasors of every probe and harmonic (one slope common to
all: a coarse estimate from the mean turn between consecutive revolutions, refined by a weighted
least-squares line through each phasor's small residual phase, each weighted by its |R|^2 over its
scatter); `aligned` turns each revolution back by h 2 pi s (k - k_mid) before averaging, so their
mean's phase is to the trigger of the middle revolution (a shift of the spin angle's origin, the
same for every probe, h times for harmonic h: the sweep's fitted spin phase takes it), and its
first-order sensitivity to an error of s is nil. SI: s is a fraction, phasors in their own unit.

A sweep's block has the same drift at any ratio: `fit_spin_turns` fits each revolution's spin
harmonics at the commanded spin turns per board revolution (beside the orbit's 1x), turns them back
by the commanded turn and fits what still turns with `fit_slip`: the block's own ratio, which the
sweep places the runout with when it is resolved (SpinTurns.used).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

import numpy as np
from numpy.typing import ArrayLike

from reduction.arrays import ComplexArray
from reduction.errors import ReductionError
from reduction.memo import DesignMemo

#: the fewest revolutions the slip is fitted from (fewer: no slip fitted, s = 0)
MIN_REVOLUTIONS = 3
#: the fitted spin ratio is used when it is off the commanded one by more than this many u
RESOLVED = 3.0
#: why no slip is fitted when no phasor scatters above the floor
NO_SCATTER = "no probe's runout scatters from revolution to revolution (dead probes, or a noise-free signal)"
#: a probe's spin harmonic is fitted only if its mean over the revolutions is this many standard
#: errors from zero: noise alone never is (the chance of 5 is e^-25), while the phase of a mean
#: in the noise, and the u weighted by it, would be arbitrary (a block with no spin content then
#: "fitted" a ratio 50 % off with a u of 1 %)
DETECTION = 5.0
NO_TONE = f"no probe's spin harmonic stands {DETECTION:g} standard errors out of its noise (no runout or spin content to follow)"


@dataclass(frozen=True)
class SlipFit:
    """The fitted slip s (fraction: spin turns per orbit revolution less 1) and its standard
    uncertainty (fraction; inf when it could not be fitted); ``unfitted``: why no slip was fitted
    ("" when it was)."""

    slip: float
    slip_u: float
    unfitted: str = ""


def _turns(n: int, revolutions: ArrayLike | None = None) -> np.ndarray:
    """(N,) revolution numbers (default consecutive) less their mean."""
    k: np.ndarray = np.arange(n, dtype=float) if revolutions is None else np.asarray(revolutions, dtype=float)
    centred: np.ndarray = k - k.mean()
    return centred


def _rotation(harmonics: np.ndarray, k: np.ndarray, slip: float) -> ComplexArray:
    """(H, N) e^{-i h 2 pi s k}: each revolution (centred number ``k``) turned back by the slip."""
    rot: ComplexArray = np.exp(-2j * np.pi * slip * np.outer(harmonics, k))
    return rot


def _checked(per_revolution: ArrayLike, harmonics: ArrayLike) -> tuple[ComplexArray, np.ndarray]:
    q = np.asarray(per_revolution, dtype=complex)
    h = np.asarray(harmonics, dtype=float)
    if q.ndim != 3 or q.shape[1] != h.size:
        raise ReductionError(f"per-revolution phasors must be (probes, {h.size} harmonics, revolutions)")
    if not np.all(np.isfinite(q)):
        raise ReductionError("a per-revolution runout phasor is not finite (NaN or inf)")
    return q, h


def fit_slip(per_revolution: ArrayLike, harmonics: ArrayLike = (1, 2), revolutions: ArrayLike | None = None) -> SlipFit:
    """The slip s of the spin against the board's revolutions from ``per_revolution`` (P, H, N)
    complex phasors of P probes at spin harmonics ``harmonics`` (H,) over N revolutions (board
    revolution numbers ``revolutions``, default consecutive; the coarse turn from the consecutive
    ones), phase to each revolution's trigger. Unambiguous while |h s| < 1/2 for every h (a turn of
    harmonic h per revolution less than half a turn). A phasor of zero amplitude or whose scatter is
    at the floor (a probe reading exact zeros, a dead probe) is left out: its weight would be
    arbitrary and its u nil; so is one whose mean is within DETECTION standard errors of zero (no
    tone to follow). Fewer than MIN_REVOLUTIONS, or no phasor left: s = 0, u = inf, and
    ``unfitted`` says why."""
    q, h = _checked(per_revolution, harmonics)
    n = q.shape[2]
    if n < MIN_REVOLUTIONS:
        return SlipFit(0.0, float("inf"), f"fewer than {MIN_REVOLUTIONS} revolutions ({n})")
    k = _turns(n, revolutions)
    if k.shape != (n,):
        raise ReductionError(f"fit_slip: {k.size} revolution numbers for {n} revolutions")
    consecutive = np.ones(n - 1, bool) if revolutions is None else np.diff(np.asarray(revolutions)) == 1
    pairs = (q[:, :, 1:] * np.conj(q[:, :, :-1]))[:, :, consecutive]  # consecutive revolutions (board numbers)
    step = np.sum(pairs, axis=(0, 2))  # (H,) the mean turn per revolution
    # the coarse slip: each harmonic's turn over h, weighted by its power (the strongest leads)
    coarse = float(np.sum(np.abs(step) * np.angle(step) / h) / (2 * np.pi * max(np.sum(np.abs(step)), 1e-300)))
    turned = q * _rotation(h, k, coarse)[None]
    mean = turned.mean(axis=2, keepdims=True)
    power = np.abs(mean[..., 0]) ** 2  # (P, H)
    scatter = np.sum(np.abs(turned - mean) ** 2, axis=2) / (n - 1)  # (P, H): complex variance per revolution
    live = (power > 0) & (scatter > 1e-24 * power + 1e-300)  # (P, H) a scatter above the floor
    if not np.any(live):
        return SlipFit(0.0, float("inf"), NO_SCATTER)
    live &= power * n >= DETECTION**2 * scatter  # a mean that stands out of its own noise
    if not np.any(live):
        return SlipFit(0.0, float("inf"), NO_TONE)
    weight = np.where(live, power / np.where(live, scatter, 1.0) * 2.0, 0.0)  # 1 / var of a phase: 2 |R|^2 / var
    resid = np.angle(turned / np.where(mean == 0, 1.0, mean))  # (P, H, N), small once turned back
    kk = float(np.sum(k * k))
    slope_ph = resid @ k / kk  # (P, H) each phasor's residual slope (rad per revolution)
    wh2 = weight * (h**2)[None, :]
    total = float(np.sum(wh2))
    if total <= 0 or not np.isfinite(total):
        return SlipFit(coarse, float("inf"))
    fine = float(np.sum(weight * h[None, :] * slope_ph) / total) / (2 * np.pi)
    return SlipFit(coarse + fine, float(1.0 / (2 * np.pi * np.sqrt(total * kk))))


def aligned(per_revolution: ArrayLike, slip: float, harmonics: ArrayLike = (1, 2)) -> ComplexArray:
    """(P, H, N) the revolutions' phasors each turned back by h 2 pi ``slip`` (k - k_mid): their
    scatter is the noise's, not the slip's turn (reduction.noise.phasor_uncertainty along axis 2)."""
    q, h = _checked(per_revolution, harmonics)
    out: ComplexArray = q * _rotation(h, _turns(q.shape[2]), slip)[None]
    return out


def slipped_harmonics(values: ArrayLike, theta: ArrayLike, slip: float, harmonics: ArrayLike = (1, 2)) -> ComplexArray:
    """(P, H, N) each revolution's runout phasors at the slipped spin harmonics: ``values`` (P, N, S)
    each probe's samples of N revolutions at board angles ``theta`` (P, S) (rad), fitted per
    revolution by least squares to a constant and Re(c_h e^{i h (1 + slip) theta}) (c_h: the phasor
    at the revolution's trigger). At ``slip`` 0 it is the board harmonics' fit; at a slip it takes
    the harmonics' leakage into one another within a revolution out (the mean of 100 revolutions of
    a 0.5 % slip: the 2x's about 1 % leakage into the 1x, turning against it)."""
    return _spin_harmonics(values, theta, 1.0 + slip, harmonics, orbit=False)


def _solver(th: np.ndarray, turns: float, h: np.ndarray, orbit: bool) -> np.ndarray:
    """(P, 1 + 2H (+ 2), S) read-only least-squares solver of :func:`_spin_harmonics`' basis."""
    arg = turns * h[None, :, None] * th[:, None, :]  # (P, H, S)
    own = [np.cos(th)[:, None, :], -np.sin(th)[:, None, :]] if orbit else []
    basis = np.concatenate([np.ones_like(th)[:, None, :], np.cos(arg), -np.sin(arg), *own], axis=1)
    solver: np.ndarray = np.linalg.pinv(np.swapaxes(basis, 1, 2))
    solver.flags.writeable = False
    return solver


#: the solvers by board angles, ratio and harmonics: a block's revolutions, fitted as they arrive, share one
_SOLVERS: DesignMemo[np.ndarray] = DesignMemo(16)


def _spin_harmonics(
    values: ArrayLike, theta: ArrayLike, turns: float, harmonics: ArrayLike, orbit: bool
) -> ComplexArray:
    """(P, H, N) per revolution: least squares of ``values`` (P, N, S) at ``theta`` (P, S) to a
    constant, Re(c_h e^{i h turns theta}) and, with ``orbit``, the orbit's own Re(a e^{i theta})."""
    x = np.asarray(values, dtype=float)
    th = np.asarray(theta, dtype=float)
    h = np.asarray(harmonics, dtype=float)
    if x.ndim != 3 or th.shape != (x.shape[0], x.shape[2]):
        raise ReductionError("spin harmonics: values must be (P, N, S) and theta (P, S)")
    key = (th.shape, th.tobytes(), float(turns), h.tobytes(), orbit)
    coef = np.einsum("pks,pns->pkn", _SOLVERS.get(key, lambda: _solver(th, turns, h, orbit)), x)  # (P, 1 + 2H (+ 2), N)
    nh = h.size
    out: ComplexArray = coef[:, 1 : 1 + nh] + 1j * coef[:, 1 + nh : 1 + 2 * nh]
    return out


class TurnsBasis(StrEnum):
    """Which spin ratio a block's spin tones were taken out at (the word run.h5 stores)."""

    FITTED = "fitted"  # fitted from the block's probe samples, resolved from the commanded
    COMMANDED = "commanded"  # the commanded spin over the planned |Omega| (not fitted, or not resolved)


@dataclass(frozen=True)
class SpinTurns:
    """A block's spin turns per board revolution (omega / |Omega|): the ``commanded`` ratio, the
    ``fitted`` one (nan when not fitted) and its standard uncertainty ``u`` (inf when not fitted);
    ``unfitted``: why not ("" when fitted)."""

    commanded: float
    fitted: float
    u: float
    unfitted: str = ""

    @property
    def resolved(self) -> bool:
        """The fitted ratio is off the commanded one by more than RESOLVED times its u."""
        return bool(np.isfinite(self.u) and abs(self.fitted - self.commanded) > RESOLVED * self.u)

    @property
    def used(self) -> float:
        """The ratio the runout is placed with: the fitted one when resolved, else the commanded."""
        return self.fitted if self.resolved else self.commanded

    @property
    def basis(self) -> TurnsBasis:
        """Which ratio ``used`` is."""
        return TurnsBasis.FITTED if self.resolved else TurnsBasis.COMMANDED


def fit_spin_turns(
    values: ArrayLike, theta: ArrayLike, spin_turns: float, revolutions: ArrayLike, harmonics: ArrayLike = (1, 2)
) -> SpinTurns:
    """The spin's turns per board revolution in a block, from the probes' ``values`` (P, N, S) (m)
    of N revolutions (board numbers ``revolutions``) at board angles ``theta`` (P, S) (rad) and the
    ``spin_turns`` commanded: each revolution's spin harmonics (runout and every other spin-locked
    part) fitted at the commanded ratio beside the orbit's 1x (:func:`revolution_harmonics`), then
    :func:`harmonics_spin_turns`."""
    h = np.asarray(harmonics, dtype=float)
    return harmonics_spin_turns(_spin_harmonics(values, theta, spin_turns, h, orbit=True), spin_turns, revolutions, h)


def harmonics_spin_turns(
    per_revolution: ArrayLike, spin_turns: float, revolutions: ArrayLike, harmonics: ArrayLike = (1, 2)
) -> SpinTurns:
    """:func:`fit_spin_turns` from its revolutions' spin harmonics (P, H, N)
    (:func:`revolution_harmonics`, each revolution's own, so a growing block computes each once):
    turned back by the commanded turn per revolution, what still turns, h 2 pi (fitted -
    commanded) per revolution, fitted by :func:`fit_slip` (unambiguous while that is below half a
    turn)."""
    c = np.asarray(per_revolution)
    h = np.asarray(harmonics, dtype=float)
    n = np.asarray(revolutions, dtype=float)
    if c.shape[2] != n.size:
        raise ReductionError(f"fit_spin_turns: {c.shape[2]} revolutions of values, {n.size} revolution numbers")
    turned = c * np.exp(-2j * np.pi * spin_turns * np.outer(h, n - n[0]))[None]
    fit = fit_slip(turned, h, n)
    fitted = spin_turns + fit.slip if np.isfinite(fit.slip_u) else math.nan
    return SpinTurns(
        spin_turns,
        fitted,
        fit.slip_u,
        fit.unfitted or ("" if np.isfinite(fit.slip_u) else "no phasor weighs in the slope"),
    )


def revolution_harmonics(
    counts: ArrayLike, gains: ArrayLike, offsets: ArrayLike, theta: ArrayLike, spin_turns: float
) -> ComplexArray:
    """(P, 2, N) each revolution's spin harmonics (1x, 2x) at the commanded ``spin_turns`` beside
    the orbit's 1x, from ``counts`` (N, P, S) of P probes as the A/D board gives them, each probe's
    ``gains`` (m per count) and ``offsets`` (m), its board angles ``theta`` (P, S) (rad): what
    :func:`harmonics_spin_turns` fits the ratio from, one revolution independent of the others."""
    c = np.asarray(counts)
    g, o = np.asarray(gains, dtype=float), np.asarray(offsets, dtype=float)
    values = np.swapaxes(c, 0, 1) * g[:, None, None] + o[:, None, None]  # (P, N, S)
    return _spin_harmonics(values, theta, spin_turns, np.array([1.0, 2.0]), orbit=True)


def counts_spin_turns(
    counts: ArrayLike,
    gains: ArrayLike,
    offsets: ArrayLike,
    theta: ArrayLike,
    spin_turns: float,
    revolutions: ArrayLike,
) -> SpinTurns:
    """:func:`fit_spin_turns` of a block as the A/D board gives it: ``counts`` (N, P, S) of its
    P probes over N revolutions (board numbers ``revolutions``), each probe's ``gains`` (m per
    count) and ``offsets`` (m), its board angles ``theta`` (P, S) (rad), the commanded
    ``spin_turns``. Not fitted (u inf) for fewer than MIN_REVOLUTIONS revolutions or a count of
    revolution numbers that is not the samples'."""
    c = np.asarray(counts)
    n = np.asarray(revolutions)
    if c.ndim != 3 or c.shape[0] < MIN_REVOLUTIONS or n.shape != (c.shape[0],):
        return unfitted_turns(spin_turns)
    return harmonics_spin_turns(revolution_harmonics(c, gains, offsets, theta, spin_turns), spin_turns, n)


def commanded_speeds(spin: float, orbit: float, written: tuple[float, float] | None = None) -> tuple[float, float]:
    """rad/s, the spin and signed orbit speeds the drives were told: ``written`` (as written to
    them, each REF rounded to its count: drives.rig.RigDrives.set_speeds) when given, else the
    asked ``spin`` and ``orbit``. A written speed that is not finite, or a written orbit of 0,
    is no speed a drive was told: ValueError naming the drive (not the asked speed in its place)."""
    if written is None:
        return spin, orbit
    for drive, speed in zip(("spin", "orbit"), written):
        if not math.isfinite(speed):
            raise ValueError(f"the {drive} drive's speed as written is {speed} rad/s: no speed it was told")
    if written[1] == 0:
        raise ValueError(f"the orbit drive's speed as written is 0 rad/s (asked {orbit:.6g} rad/s): no orbit")
    return written


def commanded_turns(spin: float, orbit: float, written: tuple[float, float] | None = None) -> float:
    """The commanded spin turns per board revolution, omega / |Omega|, of the speeds the drives
    were told (:func:`commanded_speeds`: ``written``, rad/s, when given, else the asked ``spin``
    and ``orbit``). The one rule of a sweep's block (its record, its averaging rule) and of a
    calibration step's slow roll."""
    w_spin, w_orbit = commanded_speeds(spin, orbit, written)
    return w_spin / abs(w_orbit)


def unfitted_turns(spin_turns: float) -> SpinTurns:
    """The commanded ``spin_turns`` of a block with too few revolutions to fit its ratio."""
    return SpinTurns(spin_turns, math.nan, math.inf, f"no samples of {MIN_REVOLUTIONS} revolutions or more")
