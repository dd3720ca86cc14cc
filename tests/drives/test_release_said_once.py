"""`release()` then a clean exit leaves both drives at the setpoint and says so once, with the
seconds their comm-loss watchdog gives; not when the poll found a failure by then (it stopped
both): the exit stops them again and raises it, and nothing says they were left running. On the
simulator's drives over real Modbus (TCP, RTU on a pty); the trip is the simulator's own."""

from __future__ import annotations

import logging

import pytest
from support.drives_testkit import CW_RAMP_STOP, CW_RUN, RPM, open_rig, wait_until

from drives.errors import DriveFaultError
from drives.limits import DriveLimits

pytestmark = pytest.mark.timeout(30)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM)
LEFT = "both drives left running at the setpoint: with no client polling them, their comm-loss watchdog"


async def test_released_drives_are_said_left_running_once(sim, caplog):
    caplog.set_level(logging.WARNING, logger="drives")
    async with open_rig(sim, LIMITS) as r:
        await r.set_speeds(1000 * RPM, -500 * RPM)
        await r.wait_settled(hold=0.05, timeout=5)
        r.release()
    said = [rec.getMessage() for rec in caplog.records if "left running" in rec.getMessage()]
    assert said == [LEFT + " (COMM_LOSS_TIMEOUT) ramps them down 0.5 s after the last request"], said
    assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RUN


async def test_released_drives_the_poll_stopped_are_not_said_left_running(sim, caplog):
    caplog.set_level(logging.WARNING, logger="drives")
    with pytest.raises(DriveFaultError, match="tripped") as raised:
        async with open_rig(sim, LIMITS) as r:
            await r.set_speeds(1000 * RPM, -500 * RPM)
            await r.wait_settled(hold=0.05, timeout=5)
            r.release()
            sim.models[2].inject_fault(2310)  # overcurrent: the poll stops both and records it
            await wait_until(lambda: r._poll.failure is not None, 3, "the trip found by the poll")
    assert raised.value.drive == 2 and raised.value.fault_code == 2310
    assert "left running" not in caplog.text, caplog.text
    assert sim.regs(1)["CW"] == CW_RAMP_STOP and sim.regs(1)["REF"] == 0  # the spin drive stopped
