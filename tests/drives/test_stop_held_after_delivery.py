"""A stop both drives took holds until a new speed is commanded: a drive the poll then finds
running again (operation enabled: another Modbus master started it again, or its keypad) gets the
stop again at that poll, and the finding is raised to the owner (`check`, latched as a trip is).
Before, the poll kept feeding the drive's comm-loss watchdog and it ran on at the other master's
speed for as long as the rig stayed open (a sweep's prompt between radii, say).

Real parts: the simulator's drives behind Modbus TCP; the other master is a second real Modbus
client (drives.drive.Drive on a link of its own), the keypad the drive model's own."""

from __future__ import annotations

import asyncio
import time

import pytest
from support.drives_testkit import CW_RAMP_STOP, RPM, SimDrives, open_rig, wait_until

from drives.drive import Drive
from drives.errors import DriveError
from drives.limits import DriveLimits
from drives.link import ModbusLink

pytestmark = pytest.mark.timeout(60)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM)


async def _run_again(sim: SimDrives, how: str) -> None:
    """Drive 1 running at 1500 rpm again, by another master (`other`) or at its keypad."""
    if how == "keypad":
        sim.keypad_run(1, 1500.0)  # and handed back
        return
    async with ModbusLink(sim.url, timeout=0.5) as link:
        other = Drive(link, 1, "spin", bidirectional=False)
        await other.read_parameters()
        await other.start(other.reference_for(1500 * RPM))


@pytest.mark.parametrize("how", ["other", "keypad"])
async def test_a_drive_run_again_after_the_stop_is_stopped_again(tcp_sim, how):
    sim = tcp_sim
    async with open_rig(sim, LIMITS, comm_loss_timeout=5.0) as rig:  # the watchdog stops nothing here
        await rig.set_speeds(1000 * RPM, -500 * RPM)
        await rig.wait_settled(hold=0.05, timeout=10.0)
        await rig.stop(wait=True)  # both took it, both at standstill
        words, t0 = sim.models[1].control_words, time.monotonic()  # (wall s, CW) of the last CWs written
        await _run_again(sim, how)
        again = lambda: any(w == CW_RAMP_STOP and t > t0 for t, w in list(words))  # noqa: E731
        took = await sim.wait_for(again, 2.0, "the stop sent again")
        assert took < 0.5, took  # poll interval 50 ms
        await sim.wait_stopped(timeout=5.0)
        await wait_until(lambda: rig._poll.failure is not None, 2.0, "the finding recorded")  # once the stop is out
        with pytest.raises(DriveError, match=r"spin drive \(id 1\).*after the stop") as info:
            rig.check()
        assert "the ramp stop (OFF1) is sent again" in str(info.value), info.value
        with pytest.raises(DriveError, match="after the stop"):  # latched: no start undoes it
            await rig.set_speeds(500 * RPM, 100 * RPM)
        await rig.reset_faults()
        await rig.set_speeds(500 * RPM, 100 * RPM)  # a new command: the drives run again
        await rig.wait_settled(hold=0.05, timeout=10.0)


@pytest.mark.parametrize("slow_drives", ["tcp"], indirect=True)
async def test_a_drive_run_again_during_the_wait_for_standstill_is_stopped_again(slow_drives):
    """`stop` (`orbitrig drives stop`) waits for standstill along slow ramps; another master runs the
    spin drive again meanwhile: it gets the stop again at the next poll and the wait ends at
    standstill (before: it ran on at 1500 rpm and the wait ended in a timeout)."""
    sim = slow_drives
    async with open_rig(sim, LIMITS, comm_loss_timeout=5.0) as rig:
        await rig.set_speeds(1500 * RPM, -500 * RPM)
        await rig.wait_settled(hold=0.05, timeout=10.0)
        stopping = asyncio.ensure_future(rig.stop(wait=True))
        await sim.wait_for(lambda: sim.regs(1)["CW"] == CW_RAMP_STOP, 2.0, "the stop word")
        await asyncio.sleep(0.1)  # a poll read the drives stopping: the stop both took
        words, t0 = sim.models[1].control_words, time.monotonic()
        await _run_again(sim, "other")
        again = lambda: any(w == CW_RAMP_STOP and t > t0 for t, w in list(words))  # noqa: E731
        took = await sim.wait_for(again, 2.0, "the stop sent again")
        assert took < 0.5, took
        await asyncio.wait_for(stopping, 10.0)  # at standstill, no timeout
        assert sim.regs(1)["ACT"] == 0 and sim.regs(2)["ACT"] == 0
        await wait_until(lambda: rig._poll.failure is not None, 2.0, "the finding recorded")
        with pytest.raises(DriveError, match="started again by another client"):
            rig.check()
