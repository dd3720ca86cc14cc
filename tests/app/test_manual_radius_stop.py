"""Manual settings and the drives: the orbit radius is the outer spindle's offset, set by hand,
so before a point whose radius changes both drives ramp to a confirmed standstill; static
eccentricity and pressures are set with the drives turning (the paper adjusts the static
eccentricity while the apparatus runs). The operator's prompt says which."""

from __future__ import annotations

import math
import re

import pytest

from orbitrig import config as cfg
from orbitrig.run.plan import make_plan
from orbitrig.run.steps import SetManual, SetSpin, StopDrives
from support.sweep_helpers import running, small_matrix, wait_for

pytestmark = pytest.mark.timeout(150)

RPM = 2 * math.pi / 60
#: run.log's line (after "point NNNN: ") when both drives stop for the orbit radius
RADIUS_STOP = "for the orbit radius, set by hand: both drives ramped to zero"


def _stopped(sim) -> bool:
    spin, orbit = sim.speeds
    return abs(spin) < 1.0 and abs(orbit) < 1.0


def test_the_plan_stops_the_drives_before_a_new_orbit_radius_only():
    rig = cfg.load_rig()
    plan = make_plan(small_matrix(dynamic_eccentricity=[0.04, 0.096], static_eccentricity=[0.0, 0.15]), rig)
    rate = rig.ramp_rate
    for p in plan.points[1:]:
        steps = plan.point_steps(p.index)
        prev = plan.points[p.index - 1]
        stops = [s for s in steps if isinstance(s, StopDrives)]
        spin = next(s for s in steps if isinstance(s, SetSpin))
        if p.orbit_radius != prev.orbit_radius:
            assert len(stops) == 1 and steps[0] is stops[0] and isinstance(steps[1], SetManual)
            assert stops[0].duration == pytest.approx(max(prev.spin, abs(prev.blocks[-1].orbit)) / rate)
            assert spin.duration == pytest.approx(max(p.spin, abs(p.blocks[0].orbit)) / rate)  # from standstill
        else:
            assert stops == []
    changes = sum(a.orbit_radius != b.orbit_radius for a, b in zip(plan.points, plan.points[1:]))
    assert changes >= 1 and sum(isinstance(s, StopDrives) for s in plan.steps) == changes + 1  # + the run's end


async def test_a_new_orbit_radius_is_asked_for_at_standstill(tmp_path):
    matrix = small_matrix(revolutions=6, dynamic_eccentricity=[0.04, 0.096])
    async with running(tmp_path, matrix, confirm_mode="remote") as (sim, eng, rec, run):
        await wait_for(lambda: eng.waiting_step == "manual:0000", what="the first point's settings")
        assert "both drives at standstill" in eng.message
        eng.confirm("manual:0000")
        await wait_for(lambda: eng.waiting_step == "manual:0001", what="the second point's settings", timeout=90)
        assert _stopped(sim)  # hands on the orbit spindle: nothing turns
        assert "static eccentricity ratio 0 (e/C)" in eng.message and "both drives at standstill" in eng.message
        eng.confirm("manual:0001")
        outcome = await run
    assert outcome.status == "completed"
    log = (tmp_path / "run" / "run.log").read_text()
    assert f"point 0001: {RADIUS_STOP}" in log


async def test_a_new_static_eccentricity_is_asked_for_with_the_drives_turning(tmp_path):
    matrix = small_matrix(revolutions=6, static_eccentricity=[0.0, 0.15])
    async with running(tmp_path, matrix, confirm_mode="remote") as (sim, eng, rec, run):
        await wait_for(lambda: eng.waiting_step == "manual:0000", what="the first point's settings")
        eng.confirm("manual:0000")
        await wait_for(lambda: eng.waiting_step == "manual:0001", what="the second point's settings", timeout=90)
        assert not _stopped(sim)
        assert "the drives are turning: spin 1000 rpm, orbit " in eng.message
        eng.confirm("manual:0001")
        outcome = await run
    assert outcome.status == "completed"
    assert RADIUS_STOP not in (tmp_path / "run" / "run.log").read_text()


async def _verify_prompt(eng, sim, wrong: dict[str, float]):
    """Run to the point's verification prompt with the operator's hands setting `wrong` (factors
    of the asked values) at the manual-setting step; returns the hands' right setting."""
    hands = eng.access.hands
    real, asked = hands.set_manual, []

    async def mistaken(**settings):  # the operator's slip: what the real part cannot produce
        asked.append(settings)
        return await real(**{k: v * wrong.get(k, 1.0) for k, v in settings.items()})

    hands.set_manual = mistaken
    await wait_for(lambda: eng.waiting_step == "manual:0000", what="the point's settings")
    eng.confirm("manual:0000")
    await wait_for(lambda: eng.waiting_step == "verify:0000", what="the verification prompt", timeout=90)
    return lambda: real(**asked[0])


async def test_a_missed_orbit_radius_is_corrected_at_standstill(tmp_path):
    async with running(tmp_path, small_matrix(revolutions=6), confirm_mode="remote") as (sim, eng, rec, run):
        correct = await _verify_prompt(eng, sim, {"orbit_radius": 1.3})
        assert _stopped(sim)  # hands on the orbit spindle's offset: nothing turns
        measured = float(re.search(r"orbit radius ([\d.]+) µm, want 5.76 µm", eng.message).group(1))
        assert 7.0 < measured < 8.0 and "both drives at standstill" in eng.message  # 1.3 x 5.76 um set
        await correct()
        eng.confirm("verify:0000")
        outcome = await run
    assert outcome.status == "completed"
    log = (tmp_path / "run" / "run.log").read_text()
    assert f"point 0000: {RADIUS_STOP}" in log
    assert "point 0000: orbit radius and static eccentricity verified" in log


async def test_a_missed_static_eccentricity_is_corrected_with_the_drives_turning(tmp_path):
    matrix = small_matrix(revolutions=6, static_eccentricity=[0.15])
    async with running(tmp_path, matrix, confirm_mode="remote") as (sim, eng, rec, run):
        correct = await _verify_prompt(eng, sim, {"static_eccentricity": 2.0})
        assert not _stopped(sim)
        measured = float(re.search(r"static eccentricity ([\d.]+), want 0.15", eng.message).group(1))
        assert 0.25 < measured < 0.35 and "the drives are turning: spin 1000 rpm" in eng.message  # 2 x 0.15 set
        await correct()
        eng.confirm("verify:0000")
        outcome = await run
    assert outcome.status == "completed"
    assert RADIUS_STOP not in (tmp_path / "run" / "run.log").read_text()
