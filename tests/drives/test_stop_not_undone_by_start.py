"""A stop asked while `set_speeds` starts the drives is not undone by the rest of the start.

The poll finds the spin drive tripped (overcurrent as it accelerates) just as the orbit drive's
start begins: it sends both drives the ramp stop (OFF1, zero references) ahead of everything
waiting for the link. The orbit drive's start must not go on after it: before, its REF, READY and
RUN words went out after the stop and the orbit spindle ran up to its setpoint (955 rpm on the
simulator) after the trip had stopped the rig, `set_speeds` returning as if all was well. Now no
start word goes out once a stop was asked after the speeds were commanded; `set_speeds` raises the
trip. The simulator's drives behind a real Modbus server, TCP and RTU; the trip is injected at the
moment the orbit drive's start begins (its timing is what a real part cannot be made to hit)."""

from __future__ import annotations

import asyncio
import time

import pytest

from drives.drive import Drive
from drives.errors import DriveFaultError
from drives.limits import DriveLimits
from support.drives_testkit import CW_RAMP_STOP, CW_RUN, open_rig

pytestmark = pytest.mark.timeout(60)

LIMITS = DriveLimits(max_spin=400.0, max_orbit=400.0)


async def test_a_trip_stop_during_the_start_is_not_undone(sim, monkeypatch):
    orbit_words = sim.models[2].control_words
    real_start = Drive.start

    async def start(self, raw_ref, status=None, **kw):
        if self.name == "orbit":  # the spin drive is running: it trips as it accelerates
            sim.models[1].inject_fault(2310)
            deadline = time.monotonic() + 5.0
            while CW_RAMP_STOP not in [cw for _, cw in orbit_words]:  # the poll's stop went out first
                assert time.monotonic() < deadline, "the poll's stop for the trip"
                await asyncio.sleep(0.005)
        return await real_start(self, raw_ref, status, **kw)

    monkeypatch.setattr(Drive, "start", start)
    async with open_rig(sim, LIMITS) as rig:
        with pytest.raises(DriveFaultError) as raised:
            await rig.set_speeds(200.0, 100.0)
        assert raised.value.drive == 1 and raised.value.fault_code == 2310
        stopped_at = next(i for i, (_, cw) in enumerate(orbit_words) if cw == CW_RAMP_STOP)
        after = [cw for _, cw in list(orbit_words)[stopped_at:]]
        assert CW_RUN not in after, [hex(cw) for cw in after]  # no start after the stop
        await asyncio.sleep(0.3)  # 7.5 s of the drives' time: a start would have reached its setpoint
        assert sim.regs(2)["REF"] == 0 and sim.regs(2)["ACT"] == 0 and sim.rpm(2) == 0.0, sim.regs(2)
