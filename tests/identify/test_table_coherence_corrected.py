"""The orbit table's coherences gamma2 are those of what the table holds: the per-revolution
phasors with the probes' runout taken out (orbitrig.run.identification.orbit_table), not those of
the revolutions as read. A block at spin/orbit 1/0.569 with 2 um of runout at 1x spin (1 um at 2x)
on a 2.4 um orbit: as read the runout turns against the orbit from one revolution to the next and gamma2 drops
to about 0.97; with the runout out it is the clean orbit's (0.9998, noise only)."""

from __future__ import annotations

import numpy as np
import pytest

from orbitrig.config import LMS
from orbitrig.run.corrections import Corrections, spin_turns
from orbitrig.run.identification import orbit_table
from orbitrig.run.steps import Block
from orbitrig.store.records import BlockRecord
from tests.support.phasor_blocks import CH, SLOTS, phasor_block
from reduction.coherence import orbit_coherences
from reduction.fourier import phasor

THETA = 2 * np.pi * SLOTS / 360
ORBIT = 2 * np.pi * 20.0  # rad/s, 20 Hz
RHO = 1 / 0.569  # spin / orbit
K = 3.3e7  # N/m
D = np.array([2.4e-6, -2.4e-6j])  # forward circular orbit (x, y), m


def _block(runout: np.ndarray, rng: np.random.Generator) -> tuple[BlockRecord, np.ndarray]:
    """(the block as read: its probes carry `runout` (4, 2) m at 1x, 2x spin; the clean
    per-revolution phasors (N, 8) of the same revolutions without it)."""
    revs = np.arange(60)
    read, clean = [], []
    for n in revs:
        d = D * (1 + 0.01 * rng.standard_normal(2))
        ph = np.zeros(8, complex)
        ph[[CH["x_a"], CH["x_b"]]], ph[[CH["y_a"], CH["y_b"]]] = d[0], d[1]
        f = -K * d + 0.5 * (rng.standard_normal(2) + 1j * rng.standard_normal(2))  # N
        ph[[CH["fx_piezo"], CH["fx_strain"]]], ph[[CH["fy_piezo"], CH["fy_strain"]]] = f[0], f[1]
        v = np.real(ph[:, None] * np.exp(1j * THETA))
        psi = 0.7 + 2 * np.pi * RHO * n + RHO * THETA[4:]
        v_read = v.copy()
        v_read[4:] += np.real(runout[:, :1] * np.exp(1j * psi) + runout[:, 1:] * np.exp(2j * psi))
        read.append(phasor(v_read, THETA))
        clean.append(phasor(v, THETA))
    rp = np.array(read)
    coherence = np.array([orbit_coherences(*_xyf(rp, lms)) for lms in LMS])  # as block_record stores it
    rec = phasor_block(Block(0, 1, ORBIT), rp, measured=ORBIT, coherence=coherence, revolutions=revs)
    return rec, np.array(clean)


def _xyf(rp: np.ndarray, lms) -> tuple[np.ndarray, ...]:
    x, y = (rp[:, CH["x_a"]] + rp[:, CH["x_b"]]) / 2, (rp[:, CH["y_a"]] + rp[:, CH["y_b"]]) / 2
    return x, y, rp[:, CH[f"fx_{lms}"]], rp[:, CH[f"fy_{lms}"]]


@pytest.mark.parametrize("lms", LMS)
def test_gamma2_is_computed_from_the_revolutions_with_the_runout_taken_out(lms):
    rng = np.random.default_rng(7)
    runout = 2e-6 * np.exp(1j * rng.uniform(0, 2 * np.pi, (4, 2))) * np.array([1.0, 0.5])
    rec, clean = _block(runout, rng)
    corr = Corrections(runout=runout)
    spin = RHO * ORBIT
    probes = [corr.probes(rec, CH, corr.runout_basis(rec, CH, spin_turns(rec, CH, spin)))]
    table = orbit_table(spin, [rec], CH, lms, corr, probes)
    baseline = orbit_coherences(*_xyf(clean, lms))
    assert baseline.min() > 0.999  # the clean orbit: noise only
    assert rec.coherence[LMS.index(lms)].max() < 0.99  # as read: the runout turns against the orbit
    assert table.gamma2[0] == pytest.approx(baseline, abs=1e-6)
    assert abs(table.x[0] - D[0]) / abs(D[0]) < 0.01  # the table's phasors are corrected too
    uncorrected = orbit_table(spin, [rec], CH, lms)  # no corrections: the coherences as read
    assert uncorrected.gamma2[0] == pytest.approx(rec.coherence[LMS.index(lms)], abs=1e-12)
