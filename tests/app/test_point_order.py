"""The order of the operating points (orbitrig.run.point_order): per-variable changeover
times from rig.toml, the fastest order unless the matrix pins it, the dry run's two rig
times, and a resume that keeps the order its run started with."""

from __future__ import annotations

import pytest

from orbitrig import config as cfg
from orbitrig.cli.dry_run import order_line
from orbitrig.errors import ConfigError
from orbitrig.run.engine import _started_order
from orbitrig.run.plan import make_plan, summarize
from orbitrig.run.steps import SetManual
from orbitrig.run.point_order import changeover_s
from orbitrig.store.writer import RunStore

SMALL = """name = "small"
{order}
[operating]
spin_rpm = [1000.0]
recess_pressure_mpa = [0.4826, 1.0342]
pressure_ratio = [0.4]
static_eccentricity = [0.0, 0.3]
dynamic_eccentricity = [0.096]
[orbit]
ratios = [0.5, 1.2]
revolutions = [10, 10]
[[models]]
model = "kcd11"
"""


def rig_with(static_s=1800.0, recess_s=180.0):
    text = cfg.default_rig_path().read_text()
    text = text.replace("static_eccentricity_s = 1800.0", f"static_eccentricity_s = {static_s}")
    text = text.replace("recess_pressure_s = 180.0", f"recess_pressure_s = {recess_s}")
    return cfg.rig_from_text(text, "rig.toml")


def small(order: str = ""):
    return cfg.matrix_from_text(SMALL.format(order=order), "small.toml")


def manual(plan):
    return [
        (s.static_eccentricity, round(s.recess_pressure / 1e6, 4), s.duration)
        for s in plan.steps
        if isinstance(s, SetManual)
    ]


def test_the_slow_variable_changes_once_and_each_change_costs_its_own_time():
    """Written order: recess pressure outer, eccentricity inner: es changes 3 times (3 x 1800 s);
    the fastest order changes the pressure first, es once, the pressure back (180 + 1800 + 180 s)."""
    rig = rig_with()
    plan = make_plan(small(), rig)
    assert plan.order == (0, 2, 3, 1)
    assert manual(plan) == [(0.0, 0.4826, 120.0), (0.0, 1.0342, 180.0), (0.3, 1.0342, 1800.0), (0.3, 0.4826, 180.0)]
    written = make_plan(small('order = "written"'), rig)
    assert written.order == (0, 1, 2, 3)
    assert [m[2] for m in manual(written)] == [120.0, 1800.0, 180.0 + 1800.0, 1800.0]
    assert summarize(written.steps).duration - summarize(plan.steps).duration == pytest.approx(5700 - 2280, abs=1e-6)
    assert changeover_s(rig, written.points, [0, 2, 3, 1]) == pytest.approx(120 + 2160 + 1000 / 600 * 60 / 60)
    assert changeover_s(rig, written.points, [0, 1, 2, 3]) == pytest.approx(120 + 5580 + 1000 / 600 * 60 / 60)
    # the plan's points are numbered as they run; the order maps them back to the written ones
    assert [p.index for p in plan.points] == [0, 1, 2, 3]
    assert plan.points[1].label == written.points[2].label


def test_a_change_of_orbit_radius_costs_the_ramp_to_standstill_and_back():
    """The drives stop for the orbit radius (orbitrig.run.plan): between two points of the same
    spin that costs spin / rate down and up again, where another manual change costs no ramp."""
    text = SMALL.format(order="").replace("[0.0, 0.3]", "[0.0]").replace("[0.096]", "[0.04, 0.096]")
    rig = rig_with()
    points = make_plan(cfg.matrix_from_text(text, "radius.toml"), rig, range(4)).points
    radius = next(k for k in range(1, 4) if points[k].orbit_radius != points[0].orbit_radius)
    recess = next(k for k in range(1, 4) if points[k].recess_pressure != points[0].recess_pressure)
    per, ramp = rig.changeover.of(), 2 * points[0].spin / rig.ramp_rate
    assert changeover_s(rig, points, [0, radius]) == pytest.approx(120 + points[0].spin / rig.ramp_rate + per[0] + ramp)
    assert changeover_s(rig, points, [0, recess]) == pytest.approx(120 + points[0].spin / rig.ramp_rate + per[2])


def test_an_order_that_cannot_be_beaten_stays_as_written():
    """One manual variable and one spin: every order changes it as often; the written one is kept."""
    text = SMALL.format(order="").replace("[0.4826, 1.0342]", "[0.4826]").replace("[0.0, 0.3]", "[0.0, 0.15, 0.3]")
    plan = make_plan(cfg.matrix_from_text(text, "one.toml"), rig_with())
    assert plan.order == (0, 1, 2)
    assert order_line(plan, summarize(plan.steps).duration).startswith("order of the points: fastest, as written")


def test_dry_run_prints_both_rig_times_of_the_paper_matrix():
    rig = cfg.load_rig()
    plan = make_plan(cfg.load_matrix(cfg.default_matrix_path("paper")), rig)
    changes = [s for s in plan.steps if isinstance(s, SetManual) and s.changed]
    assert len(changes) == 54  # spin still changes between the manual settings, not they between spins
    es = [s.static_eccentricity for s in plan.steps if isinstance(s, SetManual)]
    assert sum(a != b for a, b in zip(es, es[1:])) == 2  # three values, two changes
    written = summarize(make_plan(plan.matrix, rig, range(108)).steps).duration
    line = order_line(plan, summarize(plan.steps).duration)
    assert line.startswith("order of the points: fastest: estimated ") and "in the written order" in line
    assert summarize(plan.steps).duration < 0.6 * written


def test_a_stored_order_is_kept_on_resume_and_a_wrong_one_refused(tmp_path):
    rig = rig_with()
    plan = make_plan(small(), rig)
    store = RunStore.create(
        tmp_path / "run",
        rig_text=rig.text,
        matrix_text=plan.matrix.text,
        matrix_name="small",
        sim=True,
        point_order=[3, 2, 1, 0],
    )
    assert RunStore.open_existing(tmp_path / "run").stored_point_order() == [3, 2, 1, 0]
    resumed = _started_order(plan, store)
    assert (
        resumed.order == (3, 2, 1, 0) and resumed.points[0].label == make_plan(small(), rig, range(4)).points[3].label
    )
    old = RunStore.create(
        tmp_path / "old", rig_text=rig.text, matrix_text=plan.matrix.text, matrix_name="small", sim=True
    )
    assert _started_order(plan, old).order == (0, 1, 2, 3)  # recorded before the order was: as written
    with pytest.raises(ConfigError, match="does not fit the matrix's 4 points"):
        make_plan(small(), rig, [0, 1, 2])
