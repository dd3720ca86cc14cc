"""A stop asked while `set_speeds` reads the drives' statuses ends the start: nothing of it goes out.

An abort's `stop_now` (OFF3) that came while `set_speeds` was reading both drives' status words,
before it commanded anything, was forgotten: the start compared later stops with the count of
stops taken after those reads, so its REF, READY and RUN words went out after the OFF3 and both
spindles ran up to the new speeds (`set_speeds` returning as if all was well); it also cleared the
emergency stop's memory, so that the stop that followed would have been a ramp stop (OFF1) into the
emergency ramp. Now the start is refused (DriveSuperseded), no start word follows the OFF3, and the
stop repeated by `set_speeds` is the emergency stop again. The simulator's drives behind a real
Modbus server, TCP and RTU; the abort is asked at the moment the first status read has returned
(its timing is what a real part cannot be made to hit)."""

from __future__ import annotations

import asyncio

import pytest

from drives.drive import Drive
from drives.errors import DriveSuperseded
from drives.limits import DriveLimits
from support.drives_testkit import CW_EMERGENCY, CW_RAMP_STOP, CW_RUN, open_rig

pytestmark = pytest.mark.timeout(60)

LIMITS = DriveLimits(max_spin=400.0, max_orbit=400.0)


async def test_an_abort_during_the_start_reads_is_not_undone(sim, monkeypatch):
    async with open_rig(sim, LIMITS) as rig:
        await rig.set_speeds(100.0, 50.0)
        await rig.wait_settled(hold=0.05, timeout=5.0)
        real_read = Drive.read_status
        aborts = []

        async def read_status(self, *args, **kw):
            st = await real_read(self, *args, **kw)
            if asyncio.current_task() is starting and not aborts:
                aborts.append(rig.stop_now(emergency=True))  # the abort, as the start reads the drives
            return st

        monkeypatch.setattr(Drive, "read_status", read_status)
        starting = asyncio.ensure_future(rig.set_speeds(200.0, 100.0))
        with pytest.raises(DriveSuperseded):
            await starting
        assert aborts and await aborts[0] == []
        monkeypatch.setattr(Drive, "read_status", real_read)
        await sim.wait_stopped(timeout=5.0)
        for dev in (1, 2):
            words = [cw for _, cw in sim.models[dev].control_words]
            after = words[words.index(CW_EMERGENCY) :]
            assert CW_RUN not in after and CW_RAMP_STOP not in after, [hex(cw) for cw in after]
        await asyncio.sleep(0.3)  # 7.5 s of the drives' time: a start would have run them up again
        for dev in (1, 2):
            assert sim.regs(dev)["REF"] == 0 and sim.regs(dev)["ACT"] == 0, sim.regs(dev)
        assert rig.stop_sent == "emergency stop (OFF3)"
