"""One late Modbus answer is retried, not a fault; a dead link is still declared lost in the same
time bound (the poll does not retry: its failed polls in a row bound the time)."""

from __future__ import annotations

import asyncio
import logging
import re

import pytest
from support.drives_testkit import CW_RUN, RPM, open_rig

from drives.errors import DriveTimeoutError
from drives.limits import DriveLimits

pytestmark = pytest.mark.timeout(30)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM)
POLL, TIMEOUT, LOSS_POLLS = 0.05, 0.1, 3  # drives_testkit.open_rig's test timings


async def test_a_single_late_answer_to_a_command_is_retried(sim):
    # 0.3 s a request (watchdog 2 s): at 0.1 s a busy host's late answers timed out polls in a row
    async with open_rig(sim, LIMITS, link_loss_polls=LOSS_POLLS, timeout=0.3, comm_loss_timeout=2.0) as r:
        for _ in range(3):  # whichever request it hits (the poll's or the command's), nothing fails
            sim.endpoint.drop_next(1)
            await r.set_speeds(1000 * RPM, -500 * RPM)
            await r.wait_settled(hold=0.05, timeout=5)
        st = r.state
        assert st.link_ok and st.link_losses == 0
        # each drop cost one retry or one failed poll; a busy host may time out an answer it handles
        # late besides (4 for 3 drops seen at 0.1 s a request), retried as the drops are
        assert r.link.retries + st.poll_failures >= 3
        for dev in (1, 2):
            assert sim.regs(dev)["CW"] == CW_RUN and sim.regs(dev)["FAULT"] == 0


async def test_a_read_is_retried_once_then_times_out(sim):
    async with open_rig(sim, LIMITS, comm_loss_timeout=5.0) as r:
        await asyncio.sleep(0.1)
        before = r.link.retries
        sim.endpoint.drop_next(1)
        await r.spin.read_status(retries=1)  # the first try is dropped (or the poll's is): answered
        sim.endpoint.set_unresponsive(True)
        loop = asyncio.get_running_loop()
        t0 = loop.time()
        with pytest.raises(DriveTimeoutError):
            await r.spin.read_status(retries=1)
        took = loop.time() - t0
        sim.endpoint.set_unresponsive(False)
        assert r.link.retries >= before + 1
        # two tries of TIMEOUT each, after at most one poll in flight (also TIMEOUT)
        assert 2 * TIMEOUT * 0.9 < took < 3 * TIMEOUT + 1.0, took


async def test_a_dead_link_is_declared_lost_in_the_same_bound(sim, caplog):
    async with open_rig(sim, LIMITS, link_loss_polls=LOSS_POLLS, comm_loss_timeout=2.0) as r:
        await r.set_speeds(1000 * RPM, 500 * RPM)
        await r.wait_settled(hold=0.05, timeout=5)
        retries = r.link.retries
        loop = asyncio.get_running_loop()
        sim.endpoint.set_unresponsive(True)
        t0 = loop.time()
        caplog.set_level(logging.ERROR, logger="drives.poll")
        while r.state.link_ok:
            assert loop.time() - t0 < 5, "link loss not declared"
            await asyncio.sleep(0.005)
        took = loop.time() - t0
        sim.endpoint.set_unresponsive(False)
        assert r.link.retries == retries  # the poll never retried
        # declared at the LOSS_POLLS-th failed poll in a row, or before it by the time since the
        # last good poll when a loaded machine delays the polls (the reconnecting polls after it fail on)
        lost = [r.getMessage() for r in caplog.records if r.getMessage().startswith("drive link lost")]
        assert len(lost) == 1, lost
        by_count = re.match(r"drive link lost \((\d+) failed polls in a row\)", lost[0])
        by_time = re.match(r"drive link lost \(since the last good poll\): .*, (\d+) request\(s\) failed", lost[0])
        assert (by_count and int(by_count[1]) == LOSS_POLLS) or (by_time and int(by_time[1]) < LOSS_POLLS), lost
        # LOSS_POLLS x (poll interval + timeout), the bound fit_heartbeat keeps under the watchdog;
        # slack for a loaded machine
        assert (LOSS_POLLS - 1) * TIMEOUT < took < LOSS_POLLS * (POLL + TIMEOUT) + 0.5, took
