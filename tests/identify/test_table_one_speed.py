"""A block is corrected at one orbit speed (orbitrig.run.corrections.block_orbit_speed): its
revolutions and its average alike, so the mean of its corrected revolutions is its corrected
average. A block measured 2 % off its planned 20 Hz, with force and probe lags of 0.2 rad +
400 µs (0.05 rad apart between the planned and the measured speed)."""

from __future__ import annotations

import numpy as np
import pytest

from orbitrig.config import LMS
from orbitrig.run.corrections import Corrections, block_orbit_speed, spin_turns
from orbitrig.run.identification import block_revolutions, orbit_table, probe_plane
from orbitrig.run.steps import Block
from orbitrig.store.records import BlockRecord
from tests.support.phasor_blocks import CH, phasor_block

PLANNED = 2 * np.pi * 20.0  # rad/s
LAG = (0.2, 400e-6)  # rad, s


def _block(measured: float, direction: int = 1) -> BlockRecord:
    rng = np.random.default_rng(3)
    rp = rng.standard_normal((12, 8)) + 1j * rng.standard_normal((12, 8))
    rp[:, 4:] *= 1e-6
    return phasor_block(Block(0, direction, direction * PLANNED), rp, measured=measured)


CORR = Corrections(
    lags={f"f{a}_{lms}": LAG for a in "xy" for lms in LMS},
    probe_lags={p: LAG for p in ("x_a", "y_a", "x_b", "y_b")},
    probe_gains={"x_a": 1.01, "y_b": 0.98},
)


@pytest.mark.parametrize("direction", [1, -1])
@pytest.mark.parametrize("lms", LMS)
def test_a_blocks_corrected_revolutions_average_to_its_corrected_average(lms, direction):
    rec = _block(1.02 * PLANNED, direction)
    spin = 2 * PLANNED
    probes = [CORR.probes(rec, CH, CORR.runout_basis(rec, CH, spin_turns(rec, CH, spin)))]
    np.testing.assert_allclose(probes[0][1].mean(axis=0), probes[0][0], rtol=1e-12, atol=0)
    table = orbit_table(spin, [rec], CH, lms, CORR, probes)
    assert table.orbit[0] == pytest.approx(1.02 * PLANNED, rel=1e-15)  # the table's row: the measured speed
    x, y, fx, fy = block_revolutions(rec, probes[0][1], CH, lms, CORR)  # the revolutions the row's u, gamma2 are of
    for rev, avg in ((x, table.x[0]), (y, table.y[0]), (fx, table.fx[0]), (fy, table.fy[0])):
        assert rev.mean() == pytest.approx(avg, rel=1e-12)
    # and that speed is the measured one: the probes turned by 0.2 rad + 1.02 |Omega| 400 µs
    x_read, _ = probe_plane(rec.phasors, CH)
    turned = np.exp(1j * (LAG[0] + 1.02 * PLANNED * LAG[1]))
    x_a, x_b = rec.phasors[CH["x_a"]] * 1.01 * turned, rec.phasors[CH["x_b"]] * turned
    assert table.x[0] == pytest.approx((x_a + x_b) / 2, rel=1e-12)


@pytest.mark.parametrize("measured", [float("nan"), 0.0, -1.0])
def test_a_block_without_a_measured_speed_is_corrected_at_the_planned_one(measured):
    rec = _block(measured)
    assert block_orbit_speed(rec) == PLANNED
    table = orbit_table(2 * PLANNED, [rec], CH, LMS[0], CORR)
    assert table.orbit[0] == PLANNED
