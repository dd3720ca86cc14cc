"""AdcReader.acquire with averaging rules, against the simulator over TCP: adaptive
stop at an uncertainty target, the maximum, and a wait that grows with the
revolutions asked and the measured orbit period."""

from __future__ import annotations

import asyncio
import math
import re

import numpy as np
import pytest

from daq.adc import AdcReader
from daq.averaging_rule import AveragingRule
from daq.errors import DaqTimeoutError
from sim.scenario_files import scenario
from sim.rig import SimRig

ORBIT = 2 * math.pi * 12.5  # rad/s
pytestmark = pytest.mark.timeout(60)


@pytest.fixture
async def adc():
    async with SimRig(scenario("clean"), speedup=20.0, can_channel=None) as rig:
        rig.local_control(spin=2 * math.pi * 30.0, orbit=ORBIT)
        await asyncio.sleep(0.05)
        cfg = rig.config.adc
        async with AdcReader(rig.adc_url, channels=len(cfg.channels), gains=cfg.gains, offsets=cfg.offsets) as a:
            yield a


async def test_adaptive_stops_at_the_target(adc):
    # the simulator's displacement channels reach 0.4 % after about 15 revolutions
    block = await adc.acquire(AveragingRule.adaptive(0.004, 5, 200), timeout=20)
    assert block.stop_reason == "target" and 5 < block.n_records < 100
    assert np.all(block.relative_uncertainty <= 0.004)
    assert block.stats.revolutions_used == block.n_records == len(block.raw_counts)
    assert block.orbit_speed == pytest.approx(ORBIT, rel=2e-3)
    # revolutions are consecutive and the block's mean is its raw counts, calibrated
    assert np.all(np.diff(block.revs) == 1)
    assert np.array_equal(block.mean, block.raw_counts.mean(axis=0) * block.gains[:, None] + block.offsets[:, None])


async def test_adaptive_stops_at_the_maximum(adc):
    block = await adc.acquire(AveragingRule.adaptive(1e-5, 5, 30), timeout=20)
    assert (block.stop_reason, block.n_records) == ("max", 30)
    assert np.all(block.relative_uncertainty > 1e-5)
    fixed = await adc.acquire(12, timeout=20)
    assert (fixed.stop_reason, fixed.n_records) == ("count", 12)


async def test_the_wait_grows_with_revolutions_and_orbit_period(adc):
    # 150 revolutions at 250 revolutions per wall second need 0.6 s: more than 0.3 s
    with pytest.raises(DaqTimeoutError, match=r"only \d+ of 150 good revolutions within 0.3 s"):
        await adc.acquire(150, timeout=0.3)
    block = await adc.acquire(150, timeout=0.3, per_revolution=3.0)
    assert block.n_records == 150


async def test_revolutions_off_the_set_orbit_speed_are_left_out():
    """A rule that names the set orbit speed takes only revolutions the timing disk measured
    within its tolerance: before the drive gets there nothing is averaged (the drops are
    counted as off_speed), once it holds the new speed the block is made of it alone."""
    async with SimRig(scenario("clean"), speedup=20.0, can_channel=None) as rig:
        rig.local_control(spin=2 * math.pi * 30.0, orbit=ORBIT)
        await asyncio.sleep(0.05)
        cfg = rig.config.adc
        async with AdcReader(rig.adc_url, channels=len(cfg.channels), gains=cfg.gains, offsets=cfg.offsets) as adc:
            rule = AveragingRule(20, 20, None, None, orbit_speed=1.2 * ORBIT, speed_tolerance=0.005)
            with pytest.raises(DaqTimeoutError) as info:
                await adc.acquire(rule, timeout=0.5)
            said = re.fullmatch(
                r"\S+: no good revolution within 0.5 s; (\d+) revolutions dropped: (\d+) at an orbit speed off the "
                r"set one; frames (\d+) good, 0 bad, 0 bytes skipped; no link drop; the timing disk measured the "
                r"orbit at ([\d.]+) rpm, the block's \|Omega\| is 900.0 rpm",
                str(info.value),
            )
            assert said is not None, str(info.value)  # words, not the reasons' Python dict
            assert int(said[1]) == int(said[2]) >= 5 and int(said[3]) >= 5
            assert float(said[4]) == pytest.approx(750.0, rel=2e-3)  # what turns: 12.5 Hz, set 1.2 x that
            assert info.value.orbit_measured == pytest.approx(ORBIT, rel=2e-3) and info.value.heard
            assert adc.stats.drop_reasons["off_speed"] >= 5
            rig.local_control(spin=2 * math.pi * 30.0, orbit=1.2 * ORBIT)
            block = await adc.acquire(rule, timeout=20)
    assert block.n_records == 20 and block.orbit_speed == pytest.approx(1.2 * ORBIT, rel=2e-3)
    assert np.all(np.abs(2 * np.pi / block.periods / (1.2 * ORBIT) - 1) <= 0.005)


def test_the_speed_check_judges_each_period():
    rule = AveragingRule(5, 5, orbit_speed=2 * math.pi * 10.0, speed_tolerance=0.01)
    periods = np.array([0.1, 0.1 / 1.009, 0.1 / 1.011, 0.1 * 1.02, np.nan])
    assert rule.off_speed(periods).tolist() == [False, False, True, True, False]  # unknown period: kept
    assert not AveragingRule(5, 5).off_speed(periods).any()  # no set speed: nothing judged
    with pytest.raises(ValueError, match="tolerance"):
        AveragingRule(5, 5, orbit_speed=1.0, speed_tolerance=0.0)
