"""Arguments after the data that a positional slip could silently take for another are
keyword-only: a caller written for an older signature (``uncertainty_budget``'s ``k`` before it
was dropped, a number put where a neighbouring number of another meaning now stands) is a
TypeError at the call, not a wrong result."""

from __future__ import annotations

import numpy as np
import pytest

from support.reduction_synthetic import frequencies, orbit_table, truth
from reduction.allocation import allocate
from reduction.adequacy_design import allocate_keeping_test
from reduction.frequency_list import time_to_target
from reduction.identify import identify
from reduction.rig_time import point_time
from reduction.sequential import next_block
from reduction.systematic import Calibration, ChannelCalibration, uncertainty_budget
from reduction.whirl import Directions

RPM = 2 * np.pi / 60


def test_a_coverage_factor_passed_positionally_to_the_budget_is_refused():
    """An old caller's ``uncertainty_budget(ident, table, cal, 2.0)`` (k = 2) once reached ``runout``."""
    table = orbit_table(truth("kcd12", {"K": (0,), "C": (0,), "D": (0,)}), frequencies(10))
    ident, cal = identify(table, "kcd12"), Calibration(fx=ChannelCalibration(gain=0.01))
    with pytest.raises(TypeError, match="positional"):
        uncertainty_budget(ident, table, cal, 2.0)  # type: ignore[misc]
    assert uncertainty_budget(ident, table, cal, runout=None).runout == {}


def test_a_point_s_seconds_take_the_block_overhead_and_ramp_rate_by_name():
    """per_block_s (s) and ramp_rate (rad/s per s) side by side: swapped, a point's time is wrong
    by minutes without a word; by name, 2 blocks of 41 turns at 0.5 x 1000 rpm + 2 x 2 s + the ramps."""
    spin = 1000 * RPM
    with pytest.raises(TypeError, match="positional"):
        point_time([0.5], spin, [40], Directions.BOTH, 2.0, 50.0)  # type: ignore[misc]
    t = point_time([0.5], spin, [40], Directions.BOTH, per_block_s=2.0)
    assert t == pytest.approx(2 * 41 * 2 * np.pi / (0.5 * spin) + 2 * 2.0, rel=1e-12)


@pytest.mark.parametrize(
    "call",
    [
        lambda: time_to_target(None, None, 0.1, 2.0),  # target (a fraction), block_overhead (s)
        lambda: allocate(None, None, 1.0, 0.1, [0.5], [1.0], [1.0], 1.0),  # scales, then target
        lambda: allocate_keeping_test(None, None, {}, 1.0, 0.1, [0.5], None, ([0.5], [40]), 2.0),
        lambda: next_block(None, None, 1.0, 0.1, None, [0.5], None, [1.0], 1.0, 0.0, 600.0),  # target, spent, cap
    ],
    ids=["time_to_target", "allocate", "allocate_keeping_test", "next_block"],
)
def test_numbers_of_other_meanings_after_the_data_are_refused_positionally(call):
    with pytest.raises(TypeError, match="positional"):
        call()
