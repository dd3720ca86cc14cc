"""The probe tracks' runout in a block's orbit phasors, and its removal.

Runout of a probe track is a signal locked to the journal's spin angle psi,
r(psi) = Re(sum_h R_h e^{i h psi}), h = 1, 2, with R_h measured at a slow roll (the spin angle's
origin there: the slow roll's trigger). During a block the spin turns rho = omega/|Omega| times per
orbit revolution: in revolution k (board revolution number n_k) psi = phi_0 + 2 pi rho (n_k - n_0)
+ rho theta, theta the orbit angle after the trigger. Its contribution to that revolution's orbit
phasor is linear in the samples: q_k = sum_h (R_h e^{i h phi_k} w . e^{i h rho theta}
+ conj(R_h) e^{-i h phi_k} w . e^{-i h rho theta}) / 2, w the channel's phasor weights
(reduction.fourier.phasor, least squares at its sampling angles).

phi_0, the spin angle at the block's first trigger, is not measured: it is the one unknown common
to all probes and harmonics, fitted from the block's own revolutions (the runout turns through
them while the orbit response stays), by a grid over one turn refined by a parabola. Removing
the fitted runout from the block's mean takes out its leakage into the orbit phasor. SI (m, rad).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from numpy.typing import ArrayLike

from reduction.arrays import ComplexArray, FloatArray, IntArray
from reduction.errors import ReductionError
from reduction.fourier import phasor_weights

GRID = 720  # phi_0 candidates over one turn
#: the fewest revolutions whose scatter fits phi_0 (fewer: the runout cannot be taken out)
MIN_REVOLUTIONS = 3


@dataclass(frozen=True)
class RunoutBasis:
    """A block's runout per unit R[p, h]: in revolution k, probe p,
    q_k(phi_0) = sum_h R[p, h] a[h, k, p] e^{i h phi_0} + conj(R[p, h]) b[h, k, p] e^{-i h phi_0};
    a, b (H, N, P) complex, ``hs`` (H,) the spin harmonics. It depends on the probes' sampling
    angles, the spin turns and the revolutions only (:func:`runout_basis`): one a block, for the
    subtraction (:func:`remove_runout`) and its uncertainty (:func:`removal_changes`) alike."""

    a: ComplexArray
    b: ComplexArray
    hs: IntArray

    def of(self, runout: ArrayLike) -> tuple[ComplexArray, ComplexArray]:
        """(a, b) (H, N, P) of the runout ``runout`` (P, H) complex R_h per probe (m)."""
        r = np.asarray(runout, dtype=complex).T[:, None, :]
        return self.a * r, self.b * np.conj(r)


def runout_basis(theta: ArrayLike, spin_turns: float, revolutions: ArrayLike, harmonics: int) -> RunoutBasis:
    """The :class:`RunoutBasis` of a block: ``theta`` (P, S) each probe's sampling angles (rad),
    ``spin_turns`` the spin turns per board revolution, ``revolutions`` (N,) board revolution
    numbers, spin harmonics 1..``harmonics`` (~0.4 ms for 4 probes, 2 harmonics, 50 revolutions)."""
    angles, steps = np.asarray(theta, dtype=float), _steps(revolutions)
    w = phasor_weights(angles)  # (P, S)
    hs = np.arange(1, harmonics + 1)
    lead = np.einsum("ps,hps->hp", w, np.exp(1j * hs[:, None, None] * spin_turns * angles[None]))
    lag = np.einsum("ps,hps->hp", w, np.exp(-1j * hs[:, None, None] * spin_turns * angles[None]))
    turn = np.exp(1j * hs[:, None] * 2 * np.pi * spin_turns * steps[None, :])  # (H, N)
    return RunoutBasis(0.5 * turn[:, :, None] * lead[:, None, :], 0.5 * np.conj(turn)[:, :, None] * lag[:, None, :], hs)


def _steps(revolutions: ArrayLike) -> FloatArray:
    r = np.asarray(revolutions, dtype=float)
    steps: FloatArray = r - r[0]
    return steps


def _at(a: np.ndarray, b: np.ndarray, hs: np.ndarray, spin_phase: float | np.ndarray) -> np.ndarray:
    """(..., N, P) runout of each revolution at ``spin_phase`` phi_0 (rad; (...) one per stacked
    basis a, b (..., H, N, P))."""
    e = np.exp(1j * hs * np.asarray(spin_phase)[..., None])[..., None, None]
    q: ComplexArray = np.sum(a * e + b * np.conj(e), axis=-3)
    return q


@functools.lru_cache(maxsize=4)
def _grid(degree: int) -> tuple[np.ndarray, np.ndarray]:
    """The phi_0 grid (G,) and e^{i n phi} (G, 2 degree + 1) for n = -degree..degree."""
    phi = np.linspace(0.0, 2 * np.pi, GRID, endpoint=False)
    return phi, np.exp(1j * np.outer(phi, np.arange(-degree, degree + 1)))


def _best_phase(p: np.ndarray, a: np.ndarray, b: np.ndarray, hs: np.ndarray) -> FloatArray:
    """The phi_0 minimising sum |dev - m(phi_0)|^2 (dev: the phasors less their mean, m: the runout
    model less its mean), one per stacked basis a, b (..., H, N, P) (shape (...), rad). With
    z = e^{i phi_0} the cost is a trigonometric polynomial in phi_0 of degree 2H, built from inner
    products and evaluated on the grid, all stacked bases at once; a parabola refines the minimum.
    The products are einsum's own loops, not BLAS: the grid's (720, 2 degree + 1) product took 20 ms
    a fit on two busy cores with OpenBLAS's thread per core, 0.05 ms with one thread."""
    a, b = a - a.mean(axis=-2, keepdims=True), b - b.mean(axis=-2, keepdims=True)
    dev = p - p.mean(axis=0)
    terms = np.concatenate([a, b], axis=-3)  # (..., 2H, N, P): m = sum_j terms[j] z^orders[j]
    orders = [int(h) for h in hs] + [-int(h) for h in hs]
    cross = np.einsum("...inp,np->...i", np.conj(terms), dev)  # <t_i, dev>
    gram = np.einsum("...inp,...knp->...ik", np.conj(terms), terms)  # <t_i, t_k>
    degree = 2 * int(hs.max())
    coef = np.zeros(terms.shape[:-3] + (2 * degree + 1,), dtype=complex)  # z^n at index n + degree
    for i, n in enumerate(orders):
        coef[..., degree - n] -= 2 * cross[..., i]  # -2 Re <m, dev>: conj(z^n) = z^-n
        for k, m in enumerate(orders):
            coef[..., degree + m - n] += gram[..., i, k]  # <t z^n, u z^m> = z^(m - n) <t, u>
    phi, waves = _grid(degree)
    cost = np.real(np.einsum("gk,...k->...g", waves, coef))  # (..., G)
    i = np.argmin(cost, axis=-1)[..., None]
    c0, c1, c2 = (np.take_along_axis(cost, (i + j) % GRID, axis=-1)[..., 0] for j in (-1, 0, 1))
    den = c0 - 2 * c1 + c2
    shift = np.divide(0.5 * (c0 - c2), den, out=np.zeros_like(den), where=den > 0)
    best: FloatArray = (phi[i[..., 0]] + shift * (2 * np.pi / GRID)) % (2 * np.pi)
    return best


def runout_phasors(
    runout: np.ndarray, theta: np.ndarray, spin_turns: float, revolutions: np.ndarray, spin_phase: float
) -> np.ndarray:
    """(N, P) runout in each revolution's orbit phasor: ``runout`` (P, H) complex R_h per probe (m),
    ``theta`` (P, S) each probe's sampling angles (rad), ``revolutions`` (N,) board revolution
    numbers, ``spin_phase`` phi_0 (rad) at the first of them."""
    r = np.asarray(runout, dtype=complex)
    basis = runout_basis(theta, spin_turns, revolutions, r.shape[1])
    return _at(*basis.of(r), basis.hs, spin_phase)


def fit_spin_phase(
    record_phasors: np.ndarray, runout: np.ndarray, theta: np.ndarray, spin_turns: float, revolutions: np.ndarray
) -> float:
    """phi_0 (rad) that best explains the scatter of the probes' per-revolution phasors
    ``record_phasors`` (N, P) by the runout (least squares over a grid of one turn refined by a
    parabola, each probe's mean free)."""
    p, r = _checked(record_phasors), np.asarray(runout, dtype=complex)
    basis = runout_basis(theta, spin_turns, revolutions, r.shape[1])
    return float(_best_phase(p, *basis.of(r), basis.hs))


def remove_runout(record_phasors: np.ndarray, runout: np.ndarray, basis: RunoutBasis) -> np.ndarray:
    """The probes' per-revolution phasors (N, P) with the runout ``runout`` (P, H) (m) taken out,
    placed by the block's ``basis`` (:func:`runout_basis`), its spin phase fitted."""
    p = _checked(record_phasors)
    a, b = basis.of(runout)
    cleaned: ComplexArray = p - _at(a, b, basis.hs, _best_phase(p, a, b, basis.hs))
    return cleaned


def removal_changes(
    record_phasors: np.ndarray, runout: np.ndarray, basis: RunoutBasis, steps: np.ndarray
) -> ComplexArray:
    """(P, H, 2, P) change of the mean of the cleaned revolutions (:func:`remove_runout`, each
    probe's column) when the runout subtracted, R[p, h], moves by ``steps`` (P, H) (m) along its
    real part (index 0) or by i ``steps`` along its imaginary part (1), phi_0 fitted again:
    the sensitivity of a block's corrected mean to the runout's uncertainty, one step per source.
    ``basis`` the block's, as :func:`remove_runout` took it. The 1 + 2 P H fits (the runout as
    given, then each step) are stacked: one evaluation of the grid."""
    p = _checked(record_phasors)
    r = np.asarray(runout, dtype=complex)
    unit_a, unit_b, hs = basis.a, basis.b, basis.hs  # per unit R[p, h]
    a, b = basis.of(r)
    # the subtracted runout as read (row 0) and each source's step (rows 1..Q), fitted together
    probe, harmonic = (np.repeat(ix.ravel(), 2) for ix in np.indices(r.shape))  # (Q,) each
    d = np.tile([1.0, 1j], r.size) * np.asarray(steps, dtype=float)[probe, harmonic]
    rows = np.arange(1, d.size + 1)
    a2 = np.repeat(a[None], d.size + 1, axis=0)  # (1 + Q, H, N, P)
    b2 = np.repeat(b[None], d.size + 1, axis=0)
    a2[rows, harmonic, :, probe] += d[:, None] * unit_a[harmonic, :, probe]
    b2[rows, harmonic, :, probe] += np.conj(d)[:, None] * unit_b[harmonic, :, probe]
    means = _at(a2, b2, hs, _best_phase(p, a2, b2, hs)).mean(axis=-2)  # (1 + Q, P)
    out: ComplexArray = (means[0] - means[1:]).reshape(r.shape + (2, r.shape[0]))
    return out


def _checked(record_phasors: ArrayLike) -> ComplexArray:
    p = np.asarray(record_phasors, dtype=complex)
    if p.ndim != 2 or p.shape[0] < MIN_REVOLUTIONS:
        raise ReductionError(f"at least {MIN_REVOLUTIONS} revolutions are needed to fit the spin phase of the runout")
    return p
