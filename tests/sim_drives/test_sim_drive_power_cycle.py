"""A drive power-cycled while it runs (sim fault drive_power_cycle): it comes up as from power-on,
its parameters back to their defaults, while the spindle coasts down (fake clock, no I/O)."""

from __future__ import annotations

import pytest
from support.sim_drive_helpers import ACCEL_TIME, ACT, CW, READY, REF, RUN, FakeClocks, ref_counts, s16

from sim.drive_model import DriveModel


def test_a_power_cycle_brings_the_drive_up_as_from_power_on_while_it_coasts():
    clocks = FakeClocks()
    d = DriveModel(2, clock=clocks.sim_clock, bidirectional=True, wall_clock=clocks.wall_clock)
    d.write(ACCEL_TIME, [20])  # 2 s per 3000 rpm
    d.write(REF, [ref_counts(900.0)])
    d.write(CW, [READY])
    d.write(CW, [RUN])
    clocks.tick(1.0)
    d.advance()
    assert d.running and d.actual_rpm == pytest.approx(900.0, abs=1.0)
    d.power_cycle()
    assert not d.running and d.state == "switch_on_inhibited" and d.fault_code == 0
    assert d.read(0, 3) == [0, 0, 0]  # CW, REF, REF2
    assert d.read(100, 6) == [3000, 2500, 50, 50, 10, 5]  # the parameters' defaults
    clocks.tick(1.0)
    d.advance()
    assert 0.0 < d.actual_rpm < 900.0 - 100.0  # coasting (150 rpm/s), not held
    assert s16(d.read(ACT, 1)[0]) > 0  # ACT still reads the coasting speed
