"""A block's averaging rule is set at the speeds the drives were told
(reduction.runout_slip.commanded_speeds): its off-speed revolutions are judged against the orbit
speed as written (each REF rounded to its count, 0.15 rpm at SPEED_SCALE 3000 rpm), as its spin
turns are. 100 rpm asked is written as 667 counts, 100.05 rpm, 0.05 % off: at a 0.04 % tolerance
every revolution turned at the written speed was left out against the asked one. A written speed
that is not finite is an error naming the drive, not the asked speed in its place. A calibration
step's slow roll (roll_rule) alike.

Pure: no part of the rig is needed to build a rule."""

from __future__ import annotations

import math

import numpy as np
import pytest

from daq.averaging_rule import AveragingRule
from drives.registers import ref_to_rpm, rpm_to_ref
from orbitrig.config import RPM
from orbitrig.run.averaging import averaging_rule, roll_rule
from orbitrig.run.steps import Acquire, Block

SCALE_RPM = 3000.0  # the drives' SPEED_SCALE
TOLERANCE = 0.0004  # orbit_speed_tol_pct = 0.04
STEP = Acquire(point=0, duration=1.0, block=Block(0, -1, -100 * RPM), revolutions=20, hold=1.0)
SPIN = 150 * RPM


def _written(rpm: float) -> float:
    """rad/s of `rpm` as written to a drive: its REF rounded to a count."""
    return ref_to_rpm(rpm_to_ref(rpm, SCALE_RPM), SCALE_RPM) * RPM


WRITTEN = (_written(150), _written(-100))


def test_off_speed_revolutions_are_judged_at_the_orbit_speed_as_written():
    assert WRITTEN[1] / RPM == pytest.approx(-100.05, abs=1e-9)
    rule = averaging_rule(STEP, SPIN, TOLERANCE, written=WRITTEN)
    assert rule.orbit_speed == pytest.approx(100.05 * RPM, rel=1e-12)
    assert rule.spin_turns == pytest.approx(150 / 100.05, rel=1e-12)
    turned = np.full(20, 2 * math.pi / abs(WRITTEN[1]))  # s, each revolution at the written speed
    assert not rule.off_speed(turned).any()
    asked = AveragingRule(20, 20, None, 1.5, 100 * RPM, TOLERANCE)  # the asked |Omega| would leave all out
    assert asked.off_speed(turned).all()
    off = np.array([2 * math.pi / (abs(WRITTEN[1]) * f) for f in (1.0003, 1.0005, 0.9995)])
    assert rule.off_speed(off).tolist() == [False, True, True]


def test_without_written_speeds_the_rule_is_at_the_asked_ones():
    rule = averaging_rule(STEP, SPIN, TOLERANCE)
    assert rule.orbit_speed == pytest.approx(100 * RPM, rel=1e-12)
    assert rule.spin_turns == pytest.approx(1.5, rel=1e-12)


@pytest.mark.parametrize(
    ("written", "drive"),
    [((math.nan, WRITTEN[1]), "spin"), ((WRITTEN[0], math.nan), "orbit"), ((WRITTEN[0], math.inf), "orbit")],
)
def test_a_written_speed_not_finite_is_an_error_naming_the_drive(written, drive):
    with pytest.raises(ValueError, match=f"the {drive} drive's speed as written is (nan|inf) rad/s"):
        averaging_rule(STEP, SPIN, TOLERANCE, written=written)


def test_a_written_orbit_of_zero_is_an_error_naming_the_orbit_drive():
    with pytest.raises(ValueError, match="the orbit drive's speed as written is 0 rad/s"):
        averaging_rule(STEP, SPIN, TOLERANCE, written=(WRITTEN[0], 0.0))


def test_a_slow_roll_is_judged_at_the_orbit_speed_as_written_too():
    written = (_written(1000), _written(650 * 0.1))  # 65 rpm is written as 433 counts, 64.95 rpm
    rule = roll_rule(5, 1000 * RPM, 65 * RPM, TOLERANCE, written)
    assert (rule.min_revolutions, rule.max_revolutions, rule.target) == (5, 5, None)
    assert rule.orbit_speed == pytest.approx(64.95 * RPM, rel=1e-12)
    assert rule.spin_turns == pytest.approx(1000.05 / 64.95, rel=1e-12)
    assert not rule.off_speed(np.full(5, 2 * math.pi / written[1])).any()
    assert roll_rule(5, 1000 * RPM, 65 * RPM, TOLERANCE).off_speed(np.full(5, 2 * math.pi / written[1])).all()
    with pytest.raises(ValueError, match="the spin drive's speed as written is nan rad/s"):
        roll_rule(5, 1000 * RPM, 65 * RPM, TOLERANCE, (math.nan, written[1]))
