"""A cancellation wherever the speed command happens to be (each await in `set_speeds`: the
status reads, each drive's REF / ready / run words, the waits for the status word): the drives
end with the stop word as the last control word each took, REF 0, at standstill, and the
cancellation is raised. The cancel lands after 1, 2, ... 40 turns of the event loop, then
after growing delays from 1 ms, until the start is done before it, on the simulator's drives over real Modbus (TCP, RTU on a pty)."""

from __future__ import annotations

import asyncio

import pytest
from support.drives_testkit import CW_RAMP_STOP, RPM, open_rig

from drives.limits import DriveLimits

pytestmark = pytest.mark.timeout(180)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM)


async def test_a_cancel_anywhere_in_the_start_leaves_both_drives_stopped_by_the_stop_word(sim):
    cancelled = 0
    async with open_rig(sim, LIMITS, comm_loss_timeout=5.0) as rig:  # the watchdog stops nothing here
        for turns in range(1, 200):
            start = asyncio.ensure_future(rig.set_speeds(1000 * RPM, -500 * RPM))
            for _ in range(min(turns, 40)):
                await asyncio.sleep(0)
            await asyncio.sleep(0.001 * 1.25 ** (turns - 40) if turns > 40 else 0)  # then ms, growing
            if start.done():  # the start returned before the cancel: every await has been hit
                start.result()
                break
            start.cancel()
            with pytest.raises(asyncio.CancelledError):
                await start
            cancelled += 1
            for dev in (1, 2):  # the stop went out before the cancellation was raised
                regs = sim.regs(dev)
                assert (regs["CW"], regs["REF"]) == (CW_RAMP_STOP, 0), (turns, dev, regs)
            await sim.wait_stopped(timeout=5.0)
            rig.check()  # nothing found wrong: the stop was the start's own
        else:
            raise AssertionError("the start never returned")
        assert cancelled >= 10, cancelled  # the start's awaits: two reads, six writes, the status waits
        await rig.stop()
