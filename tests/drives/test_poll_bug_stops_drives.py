"""A drive poll that fails on a bug (not a DriveError: a decoding error, say) can no longer
judge the drives: a trip would go unseen while its reads keep the drives' comm-loss watchdog
fed. Commanded drives are then ramped to zero at once, as after a trip, and the failure is
raised to the owner (`RigDrives.check`, `wait_settled`).

Real parts: the simulator's drives behind Modbus TCP; the bug is injected (no real part
produces one)."""

from __future__ import annotations

import asyncio

import pytest
from support.drives_testkit import CW_RAMP_STOP, CW_RUN, RPM, open_rig, wait_until

from drives.errors import DriveError
from drives.limits import DriveLimits
from drives.poll import DrivePoll

pytestmark = pytest.mark.timeout(30)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM)


async def test_a_poll_that_fails_on_a_bug_ramps_both_commanded_drives_to_zero(tcp_sim, monkeypatch, caplog):
    sim = tcp_sim
    async with open_rig(sim, LIMITS) as rig:
        await rig.set_speeds(1000 * RPM, -500 * RPM)
        await rig.wait_settled(hold=0.1, timeout=10.0)
        assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RUN

        def broken(self, statuses, *, link_ok, link_error=None):
            raise ValueError("status word decoding bug")

        monkeypatch.setattr(DrivePoll, "publish", broken)  # every poll from now on fails
        took = await sim.wait_for(
            lambda: sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RAMP_STOP, 2.0, "both drives' stop words"
        )
        assert took < 1.0, took  # poll interval 50 ms: the first failed poll sends them
        heard = sim.models[1].last_request
        await asyncio.sleep(0.5)  # about ten more polls fail, logged no more
        assert sim.models[1].last_request > heard  # the poll's reads go on (the heartbeat)
        with pytest.raises(DriveError, match=r"poll failed: ValueError\('status word decoding bug'\)"):
            rig.check()
        monkeypatch.undo()  # the poll reads the drives again: their ramp is watched to standstill
        await sim.wait_stopped(10.0)
    failed = [r for r in caplog.records if r.getMessage().startswith("drive poll failed")]
    assert [r.getMessage() for r in failed] == ["drive poll failed; ramping both drives to zero"], len(failed)
    assert failed[0].exc_info is not None  # its traceback


async def test_a_poll_that_fails_on_a_bug_while_a_stop_is_owed_sends_it_again(tcp_sim, monkeypatch):
    """A stop no drive took is owed; the polls after it fail on a bug, so none of them can find
    the drives still running: the owed stop goes out again at the first failed poll that
    reaches the drives, as a poll that read them would send it."""
    sim = tcp_sim
    async with open_rig(sim, LIMITS, comm_loss_timeout=5.0) as rig:  # the watchdog stops nothing here
        await rig.set_speeds(1000 * RPM, -500 * RPM)
        await rig.wait_settled(hold=0.1, timeout=10.0)
        sim.endpoint.set_unresponsive(True)
        with pytest.raises(DriveError, match="no answer"):
            await rig.stop(wait=False)
        assert rig._poll.owed is False and sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RUN

        def broken(self, statuses, *, link_ok, link_error=None):
            raise ValueError("status word decoding bug")

        monkeypatch.setattr(DrivePoll, "publish", broken)  # every poll from now on fails
        sim.endpoint.set_unresponsive(False)
        took = await sim.wait_for(
            lambda: sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RAMP_STOP, 3.0, "the owed stop at both drives"
        )
        assert took < 1.0, took  # poll interval 50 ms: the first poll that reaches them sends it
        await wait_until(lambda: rig._poll.owed is None, 2.0, "the owed stop delivered to both")
        monkeypatch.undo()
        await sim.wait_stopped(10.0)
