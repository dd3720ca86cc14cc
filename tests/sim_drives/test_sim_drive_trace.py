"""The drive's speed over simulated time (DriveModel.trace, sim/speed_trace.py), which the orbit
spindle turns by: read back at any time since, however seldom the drive was advanced."""

from __future__ import annotations

import numpy as np
from support.sim_drive_helpers import CW, READY, REF, RUN, FakeClocks, ref_counts

from sim.drive_model import DriveModel

# Defaults: ACCEL/DECEL 5 s per 3000 rpm -> 600 rpm/s.


def test_a_ramp_and_its_hold_read_back_from_one_late_advance():
    clocks = FakeClocks()
    d = DriveModel(2, clock=clocks.sim_clock, bidirectional=True, wall_clock=clocks.wall_clock)
    d.write(REF, [ref_counts(1200.0)])
    d.write(CW, [READY])
    d.write(CW, [RUN])
    clocks.tick(10.0)
    d.advance()  # once, 10 s after the start: up in 2 s, held 8 s
    at = d.trace.at(np.array([0.5, 1.0, 2.0, 5.0, 10.0]))
    np.testing.assert_allclose(at, [300.0, 600.0, 1200.0, 1200.0, 1200.0])
    d.write(REF, [ref_counts(-600.0)])  # at 10 s: down through zero to -600 rpm
    clocks.tick(10.0)
    d.advance()
    at = d.trace.at(np.array([11.0, 12.0, 12.5, 13.0, 20.0]))
    np.testing.assert_allclose(at, [600.0, 0.0, -300.0, -600.0, -600.0], atol=1e-6)
    assert len(d.trace.times()) <= 8  # knots at the changes of slope, a hold's two


def test_the_keypads_speed_is_a_jump():
    clocks = FakeClocks()
    d = DriveModel(2, clock=clocks.sim_clock, bidirectional=True, wall_clock=clocks.wall_clock)
    clocks.tick(1.0)
    d.local_control(300.0)
    clocks.tick(4.0)
    d.advance()
    np.testing.assert_allclose(d.trace.at(np.array([0.5, 1.0 - 1e-6, 1.0 + 1e-6, 5.0])), [0.0, 0.0, 300.0, 300.0])
