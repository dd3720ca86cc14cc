"""The wait for standstill after a stop asks the poll for statuses, as the wait for the setpoint
does: one right after the stop command (drives at standstill already, as at the end of a run
whose last step stopped them), then every quarter interval until both read zero speed; it does
not wait for the poll's pace, up to an interval after the drives got there."""

from __future__ import annotations

import time

import pytest
from support.drives_testkit import RPM, open_rig

from drives.limits import DriveLimits

pytestmark = pytest.mark.timeout(30)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM, min_ratio=None, max_ratio=1.0)
POLL = 0.5  # s between polls at the pace: far longer than the waits below


async def test_a_stop_of_drives_at_standstill_is_confirmed_at_once_not_at_the_next_poll(tcp_sim):
    async with open_rig(tcp_sim, LIMITS, poll_interval=POLL, timeout=0.3, comm_loss_timeout=2.0) as r:
        took = []
        for _ in range(3):
            t0 = time.monotonic()
            await r.stop(timeout=5)
            took.append(time.monotonic() - t0)
            assert r.state.stopped and r.state.time > t0
    assert max(took) < POLL / 4, took


async def test_a_ramp_stop_is_confirmed_soon_after_standstill(tcp_sim):
    async with open_rig(tcp_sim, LIMITS, poll_interval=POLL, timeout=0.3, comm_loss_timeout=2.0) as r:
        await r.set_speeds(600 * RPM, 300 * RPM)
        await r.wait_settled(hold=0.05, timeout=5)
        t0 = time.monotonic()
        await r.stop(timeout=5)
        took = time.monotonic() - t0
        assert r.state.stopped and tcp_sim.regs(1)["ACT"] == tcp_sim.regs(2)["ACT"] == 0
    # the drives' ramp from 600 rpm: 1 s at 600 rpm/s, 0.04 s wall at the testkit's speed-up of 25
    assert took < 0.04 + POLL / 4 + 0.1, took
