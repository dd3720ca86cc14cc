"""The runout's spin-phase fits stacked (reduction.runout): removal_changes fits the block's spin
phase for the subtracted runout and for each of its 16 steps in one evaluation of the grid, and
gives the numbers the one-step-at-a-time fits gave (REFERENCE below, the former code) within float
rounding: 1e-9 relative of the largest change, the phase within 1e-9 rad."""

from __future__ import annotations

import numpy as np
import pytest

from reduction import runout
from reduction.runout import GRID, fit_spin_phase, removal_changes, runout_phasors


def _reference_phase(p, a, b, hs) -> float:
    """The former single fit: the cost's coefficients by vdot, the grid by a matrix product."""
    a, b = a - a.mean(axis=1, keepdims=True), b - b.mean(axis=1, keepdims=True)
    dev = p - p.mean(axis=0)
    terms = [(h, a[i]) for i, h in enumerate(hs)] + [(-h, b[i]) for i, h in enumerate(hs)]
    degree = 2 * int(hs.max())
    coef = np.zeros(2 * degree + 1, dtype=complex)
    for n, t in terms:
        coef[degree - n] -= 2 * np.vdot(t, dev)
        for k, u in terms:
            coef[degree + k - n] += np.vdot(t, u)
    phi, waves = runout._grid(degree)
    cost = np.real(waves @ coef)
    i = int(np.argmin(cost))
    c0, c1, c2 = cost[i - 1], cost[i], cost[(i + 1) % GRID]
    den = c0 - 2 * c1 + c2
    shift = 0.5 * (c0 - c2) / den if den > 0 else 0.0
    return float((phi[i] + shift * (2 * np.pi / GRID)) % (2 * np.pi))


def _reference_changes(p, r, theta, spin_turns, revolutions, steps):
    """The former removal_changes: one copy of the basis and one fit per step."""
    unit = runout.runout_basis(theta, spin_turns, revolutions, r.shape[1])
    (a, b), unit_a, unit_b, hs = unit.of(r), unit.a, unit.b, unit.hs
    base = runout._at(a, b, hs, _reference_phase(p, a, b, hs)).mean(axis=0)
    out = np.zeros(r.shape + (2,) + (r.shape[0],), dtype=complex)
    for i, h in np.ndindex(*r.shape):
        for part, unit in enumerate((1.0, 1j)):
            d = unit * float(steps[i, h])
            a2, b2 = a.copy(), b.copy()
            a2[h, :, i] += d * unit_a[h, :, i]
            b2[h, :, i] += np.conj(d) * unit_b[h, :, i]
            out[i, h, part] = base - runout._at(a2, b2, hs, _reference_phase(p, a2, b2, hs)).mean(axis=0)
    return out


def _case(seed: int):
    """A block of 3 to 80 revolutions (board numbers with gaps), 4 probes of 16 to 90 samples at
    random angles, a random runout, spin ratio and spin phase, noise from 0.1 nm to 0.3 µm."""
    rng = np.random.default_rng(seed)
    n, s = int(rng.integers(3, 81)), int(rng.integers(16, 91))
    theta = np.sort(rng.uniform(0, 2 * np.pi, (4, s)), axis=1)
    r = (rng.normal(size=(4, 2)) + 1j * rng.normal(size=(4, 2))) * 1e-7 * rng.uniform(0.1, 3)
    rho = float(rng.uniform(0.3, 4))
    revs = np.cumsum(rng.integers(1, 3, n)) - 1
    noise = 10 ** rng.uniform(-10, -6.5) * (rng.normal(size=(n, 4)) + 1j * rng.normal(size=(n, 4)))
    p = runout_phasors(r, theta, rho, revs, float(rng.uniform(0, 2 * np.pi))) + noise + 1e-6 * rng.normal(size=4)
    return p, r, theta, rho, revs, rng.uniform(0, 5e-8, (4, 2))


@pytest.mark.parametrize("seed", range(0, 60, 3))
def test_removal_changes_are_the_one_step_at_a_time_fits(seed: int) -> None:
    p, r, theta, rho, revs, steps = _case(seed)
    old = _reference_changes(p, r, theta, rho, revs, steps)
    new = removal_changes(p, r, runout.runout_basis(theta, rho, revs, 2), steps)
    assert new.shape == (4, 2, 2, 4)
    assert np.max(np.abs(new - old)) <= 1e-9 * np.max(np.abs(old))
    basis = runout.runout_basis(theta, rho, revs, 2)
    a, b, hs = *basis.of(r), basis.hs
    turn = fit_spin_phase(p, r, theta, rho, revs) - _reference_phase(p, a, b, hs)
    assert abs((turn + np.pi) % (2 * np.pi) - np.pi) < 1e-9


def test_stacked_bases_each_get_their_own_phase() -> None:
    """A stack of bases (..., H, N, P) is fitted row by row: each row's phase is its own single
    fit, rows of differently turned runouts (a stack of 3 x 2) keep theirs."""
    p, r, theta, rho, revs, _ = _case(7)
    rng = np.random.default_rng(8)
    unit = runout.runout_basis(theta, rho, revs, 2)
    bases = [(*unit.of(r * np.exp(1j * rng.uniform(-1, 1, r.shape))), unit.hs) for _ in range(6)]
    a = np.array([x[0] for x in bases]).reshape((3, 2) + bases[0][0].shape)
    b = np.array([x[1] for x in bases]).reshape((3, 2) + bases[0][1].shape)
    hs = bases[0][2]
    got = runout._best_phase(p, a, b, hs)
    assert got.shape == (3, 2)
    want = np.array([_reference_phase(p, x[0], x[1], hs) for x in bases]).reshape(3, 2)
    assert np.max(np.abs(got - want)) < 1e-9
    assert np.ptp(want) > 0.01  # the rows differ: a fit shared across the stack would fail
