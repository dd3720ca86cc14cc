"""A drive that trips while both are in their emergency stop (OFF3): the poll stops both again
for the trip, and that stop stays the emergency stop. It sent the ramp stop (OFF1) instead, which
turned the other drive's emergency ramp into its ten times slower ramp stop. So do the poll's other
stops (a bug in a poll, its crash, a drive found running again) and the rig's own, until a new speed
is commanded. On the simulator's drives over real Modbus (TCP, RTU on a pty), ramps slowed
(DECEL_TIME 90 s for 3000 rpm, at 3 x: the emergency stop about 1.5 s wall from 1500 rpm, the ramp
stop 15 s); the trip is the simulator's own (overcurrent 2310, a coast stop)."""

from __future__ import annotations

import asyncio
import re
import contextlib
import time

import pytest
from support.drives_testkit import CW_EMERGENCY, RPM, SimDrives, open_rig, set_parameter

from drives import registers as R
from drives import rig_stop as rig_module
from drives.errors import DriveFaultError
from drives.limits import DriveLimits
from drives.rig import StopTripError
from orbitrig.run.safe_stop import stop_drives

pytestmark = pytest.mark.timeout(60)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM)


def _faulted(r) -> bool:
    try:
        r.check()
    except DriveFaultError:
        return True
    return False


@contextlib.asynccontextmanager
async def _in_the_emergency_stop(sim: SimDrives):
    """The rig open on `sim`, its ramp stop slowed (DECEL_TIME 900: about 15 s) before, both drives
    brought to 1500 rpm, then the emergency stop asked, not waited for."""
    for model in sim.models.values():
        set_parameter(model, R.DECEL_TIME, 900)
    async with open_rig(sim, LIMITS) as r:
        await r.set_speeds(1500 * RPM, -1500 * RPM)
        await r.wait_settled(hold=0.05, timeout=20)
        await r.stop(emergency=True, wait=False)
        yield r


async def test_a_trip_during_the_emergency_stop_keeps_the_other_drive_in_its_emergency_stop(slow_drives):
    sim: SimDrives = slow_drives
    async with _in_the_emergency_stop(sim) as r:
        await sim.wait_for(
            lambda: sim.regs(2)["CW"] == CW_EMERGENCY and 200 < abs(sim.rpm(2)) < 1300, 5, "the emergency ramp"
        )
        sim.models[1].inject_fault(2310)  # the spin drive trips in the emergency ramp
        t_trip = time.monotonic()
        await sim.wait_for(lambda: _faulted(r), 5, "the poll's stop for the trip")
        assert sim.regs(2)["CW"] == CW_EMERGENCY, hex(sim.regs(2)["CW"])  # still the emergency stop
        await sim.wait_for(lambda: sim.rpm(2) == 0, 5, "the orbit drive at standstill")
        assert time.monotonic() - t_trip < 2.0  # along its emergency ramp, not the ramp stop's 15 s
        sim.models[1].clear_fault_cause()


async def test_a_ramp_stop_asked_after_the_emergency_stop_is_said_as_the_emergency_stop_it_sent(slow_drives):
    """`stop(emergency=False)` after the emergency stop, no speed commanded since, sends OFF3:
    what it raises for a drive tripping in that ramp (StopTripError), `stop_sent` and the run's
    log line for the stop name the emergency stop (OFF3) it sent, not the ramp stop asked."""
    sim: SimDrives = slow_drives
    async with _in_the_emergency_stop(sim) as r:
        stop = asyncio.create_task(r.stop(emergency=False, timeout=20))  # asked as a ramp stop
        await sim.wait_for(lambda: 200 < abs(sim.rpm(1)) < 1300, 5, "the emergency ramp")
        sim.models[1].inject_fault(2310)  # the spin drive trips in it
        with pytest.raises(StopTripError) as info:
            await stop
        assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_EMERGENCY  # the words sent
        assert (info.value.fault_code, info.value.standstill) == (2310, True)
        # on a loaded host the in-process orbit drive may also trip on its comm-loss watchdog (7510) while the
        # shared loop stalls; the message then names it between the two clauses
        said = r"tripped during the emergency stop \(OFF3\)(; orbit drive \(id 2\) tripped too \(fault 7510\))?; both drives at standstill"
        assert re.search(said, str(info.value)), str(info.value)
        assert r.stop_sent == "emergency stop (OFF3)"
        sim.models[1].clear_fault_cause()
        await r.reset_faults()
        # the run's closing stop asked as a ramp stop after an emergency stop: its line says OFF3
        await r.set_speeds(600 * RPM, -600 * RPM)
        await r.wait_settled(hold=0.05, timeout=20)
        r.stop_now(emergency=True)
        escalated, line = await stop_drives(r, asyncio.Event(), emergency=False, timeout=20)
        assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_EMERGENCY
        assert not escalated and line.startswith("drives: emergency stop (OFF3); standstill after "), line


async def test_a_ramp_stop_sent_as_the_emergency_stop_waits_the_emergency_ramps_time(slow_drives, monkeypatch):
    """`stop(emergency=False)` after the emergency stop goes out as OFF3, and its default wait for
    standstill is sized from that emergency ramp (a tenth of the ramp stop's 15 s here), not from the
    ramp stop asked: a drive that does not get there is said so that much sooner. (The sizing is the
    real `standstill_wait`, only recorded.)"""
    sim: SimDrives = slow_drives
    sized: list[tuple[bool, float]] = []
    real = rig_module.standstill_wait

    def standstill_wait(drives, *, emergency, poll_interval):  # the real sizing, its word recorded
        wait = real(drives, emergency=emergency, poll_interval=poll_interval)
        sized.append((emergency, wait))
        return wait

    monkeypatch.setattr(rig_module, "standstill_wait", standstill_wait)
    async with _in_the_emergency_stop(sim) as r:
        await r.stop(emergency=False)  # asked as a ramp stop, default wait
        assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_EMERGENCY
        assert [e for e, _ in sized] == [True], sized
        # from at most 1500 rpm: DECEL_TIME 90 s x 1500 / 3000 / 10 (physical s), x 1.5 + 2 s + 4 polls;
        # the ramp stop's would be ten times that ramp (about 70 s)
        assert 2.2 < sized[0][1] <= 1.5 * 90 * 1500 / 3000 / 10 + 2 + 4 * 0.05 + 1e-9, sized


async def test_a_rig_opened_during_an_emergency_ramp_stops_with_the_emergency_stop(slow_drives):
    """Both drives in the emergency ramp of an earlier owner (another process, a service's abort
    over a link of its own) when a rig is opened: read so on entry (SW OFF_3_STA 0, turning), every
    stop of the new rig is the emergency stop until it commands a speed; its ramp stop word would
    slow that ramp tenfold (the ramp stop 15 s here, the emergency ramp 1.5 s)."""
    sim: SimDrives = slow_drives
    async with _in_the_emergency_stop(sim):
        pass  # its exit sends the emergency stop again, not waited for
    t_open = time.monotonic()
    async with open_rig(sim, LIMITS) as r:
        assert abs(sim.rpm(1)) > 300 and r.entry.statuses[1].emergency_ramp, sim.rpm(1)
        await r.stop(emergency=False, timeout=20)  # asked as a ramp stop
        assert r.stop_sent == "emergency stop (OFF3)"
        assert time.monotonic() - t_open < 3.0  # along the emergency ramp
    for device, model in sim.models.items():
        words = [cw for t, cw in model.control_words if t >= t_open]
        assert words and set(words) == {CW_EMERGENCY}, (device, [hex(w) for w in words])
