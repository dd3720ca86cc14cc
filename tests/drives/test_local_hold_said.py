"""A drive held at its keypad (local control) while the stop it refused is owed: the poll sends the
stop again at every poll all the same, but says so once when it starts (naming the drive and local
control), every STILL_HELD_S s while it holds, and once when the drive takes the stop (the keypad
gave it back), not at every poll (20 a second here). On the simulator's drives over real Modbus TCP,
whose keypad refuses every control word (exception 03) until handed back."""

from __future__ import annotations

import asyncio
import logging

import pytest
from support.drives_testkit import CW_RAMP_STOP, RPM, DriveLines, SimDrives, drive_lines, open_rig

from drives import local_hold
from drives.limits import DriveLimits

pytestmark = pytest.mark.timeout(60)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM)
HELD_S = 3.0  # s the keypad holds the orbit drive after the refused stop


async def _held_then_given_back(sim: SimDrives) -> DriveLines:
    """Both drives run, the orbit drive taken at its keypad, the rig's stop refused by it, held
    HELD_S s, then given back: the lines its poll logged meanwhile and until 1 s after."""
    with drive_lines() as lines:
        async with open_rig(sim, LIMITS) as rig:
            await rig.set_speeds(100.0, -50.0)
            sim.models[2].local_control(-300.0)
            with pytest.raises(Exception, match="in local control"):
                await rig.stop(timeout=0.5)
            await asyncio.sleep(HELD_S)
            sim.models[2].hand_back()
            await sim.wait_for(lambda: sim.regs(2)["CW"] == CW_RAMP_STOP, 2.0, "the stop taken")
            await asyncio.sleep(0.3)
    return lines


async def test_a_drive_held_at_its_keypad_is_said_once_not_at_every_poll(tcp_sim):
    sim = tcp_sim
    lines = await _held_then_given_back(sim)
    refused = "orbit drive (id 2), register CW (0): did not take the ramp stop (OFF1, 0x047E): in local control"
    # the stop went again at every poll but the watchdog's starving (over the wire: each refused by the keypad)
    assert len(lines.said(logging.DEBUG, "stop command not delivered", refused)) >= 10, lines.lines
    assert len(lines.said(logging.ERROR, "stop command not delivered", refused)) == 2, lines.lines  # rig's, poll's
    assert len(lines.said(logging.ERROR, "orbit drive (id 2)", "it missed (not delivered) is sent again")) == 1
    started = lines.said(logging.WARNING, "orbit drive (id 2) in local control (status word REMOTE = 0)")
    assert started == [
        "orbit drive (id 2) in local control (status word REMOTE = 0): the operator at its keypad has it: the ramp "
        "stop (OFF1) goes again at every poll until it takes it; said again every 30 s while it holds"
    ], lines.lines
    assert not lines.said(logging.WARNING, "still in local control"), lines.lines
    (took,) = lines.said(logging.WARNING, "orbit drive (id 2) took the ramp stop (OFF1) sent again")
    held = float(took.split("sent again, ")[1].split(" s")[0])
    assert HELD_S - 0.2 <= held <= HELD_S + 1.5, took
    assert sim.regs(2)["CW"] == CW_RAMP_STOP
    await sim.wait_stopped(5.0)


async def test_a_drive_still_held_is_said_again_at_the_slow_pace(tcp_sim, monkeypatch):
    sim = tcp_sim
    monkeypatch.setattr(local_hold, "STILL_HELD_S", 0.5)
    lines = await _held_then_given_back(sim)
    still = lines.said(logging.WARNING, "orbit drive (id 2) still in local control (status word REMOTE = 0)")
    # ~2 s of the 3 s held have the stop sent again (about 1 s it is starved): a line each 0.5 s of them
    assert 2 <= len(still) <= 6, lines.lines
    assert all("s since it first refused the ramp stop (OFF1)" in line for line in still), still
    assert len(lines.said(logging.WARNING, "took the ramp stop (OFF1) sent again")) == 1, lines.lines


async def test_both_drives_held_at_their_keypads_are_each_said_once(tcp_sim):
    """The poll's finding names the first drive running; the other's refusals of the same stop sent
    again are held and said at the slow pace too, not an ERROR at every poll."""
    sim = tcp_sim
    with drive_lines() as lines:
        async with open_rig(sim, LIMITS) as rig:
            await rig.set_speeds(100.0, -50.0)
            sim.models[1].local_control(300.0)
            sim.models[2].local_control(-300.0)
            with pytest.raises(Exception, match="in local control"):
                await rig.stop(timeout=0.5)
            await asyncio.sleep(2.0)
            sim.models[1].hand_back()
            sim.models[2].hand_back()
            await sim.wait_for(lambda: sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RAMP_STOP, 2.0, "the stop taken")
            await asyncio.sleep(0.3)
    for name in ("spin drive (id 1)", "orbit drive (id 2)"):
        refused = f"{name}, register CW (0): did not take the ramp stop (OFF1, 0x047E): in local control"
        assert len(lines.said(logging.ERROR, "stop command not delivered", refused)) <= 2, lines.lines
        assert len(lines.said(logging.WARNING, f"{name} in local control (status word REMOTE = 0)")) == 1, lines.lines
        assert len(lines.said(logging.WARNING, f"{name} took the ramp stop (OFF1) sent again")) == 1, lines.lines
    await sim.wait_stopped(5.0)
