"""The run's last safe point, past which a pause is refused (orbitrig.run.control.NothingToPause):
the one before the last point's identification, whatever the points, since every point ends with
its identification and completion and the closing ramp has none. A pause asked before it is still
reached there (the drives keep their speeds); with no point left to measure (a resume of a run whose
points are all complete) there is none: the closing ramp refuses the pause (RunControl.closing_ramp)."""

from __future__ import annotations

from orbitrig import config as cfg
from orbitrig.run.plan import make_plan
from orbitrig.run.procedure import last_safe_point
from orbitrig.run.steps import Identify
from support.sweep_helpers import small_matrix


def test_the_last_safe_point_is_the_one_before_the_last_points_identification():
    plan = make_plan(small_matrix(spin_rpm=[1000.0, 2000.0]), cfg.load_rig())
    last = plan.points[-1].index
    assert len(plan.points) > 1
    step = last_safe_point(plan.steps)
    assert isinstance(step, Identify) and step.point == last, step
    assert step is [s for s in plan.point_steps(last) if isinstance(s, Identify)][0]
    after = plan.steps[plan.steps.index(step) + 1 :]
    assert [type(s).__name__ for s in after] == ["CompletePoint", "StopDrives"], after
    assert last_safe_point(plan.final_steps) is None  # every point complete before: the closing ramp only
