"""An exception raised in the rig's exit before its stop (a bug in the wait for a starved drive's
outcome, the poll ended on an exception, the release's warning) does not skip the stop: both drives get their stop
word, the link is closed, and the exception surfaces (the block's own exception goes on, the
failure noted on it and logged). On the simulator's drives over real Modbus (TCP, RTU on a
pty), which record every control word written; the raise alone is the test's (no real part
produces one)."""

from __future__ import annotations

import asyncio
import logging
import time

import pytest
from support.drives_testkit import CW_RAMP_STOP, CW_RUN, RPM, SimDrives, open_rig

from drives import rig as rig_module
from drives import way_out
from drives.errors import DriveError
from drives.limits import DriveLimits
from drives.poll_pace import PollPace
from drives.starve import Starver

pytestmark = pytest.mark.timeout(60)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM)
CW, REF = 0, 1  # register addresses


def words_since(sim: SimDrives, dev: int, t0: float) -> list[int]:
    """The control words drive `dev` took since `t0` (monotonic s), as the simulator recorded them."""
    return [cw for t, cw in sim.models[dev].control_words if t >= t0]


def stopped_since(sim: SimDrives, dev: int, t0: float) -> bool:
    """Drive `dev` took the ramp stop word since `t0`, and no other word (a retry repeats it)."""
    words = words_since(sim, dev, t0)
    return bool(words) and set(words) == {CW_RAMP_STOP}


async def at_speed(rig) -> None:
    await rig.set_speeds(1000 * RPM, -500 * RPM)
    await rig.wait_settled(hold=0.05, timeout=10.0)


def starver_bug(self):
    raise RuntimeError("starver bookkeeping bug")


async def test_a_bug_in_the_starved_outcome_wait_still_stops_both_drives_and_surfaces(sim, monkeypatch, caplog):
    caplog.set_level(logging.ERROR, logger="drives")
    rig = open_rig(sim, LIMITS)
    with pytest.raises(RuntimeError, match="starver bookkeeping bug"):
        async with rig:
            await at_speed(rig)
            assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RUN
            monkeypatch.setattr(Starver, "due", starver_bug)  # what no real part produces
            t_exit = time.monotonic()
    for dev in (1, 2):
        assert stopped_since(sim, dev, t_exit), (dev, sim.models[dev].control_words)
    assert not rig.link.connected
    said = [r for r in caplog.records if "the wait for the starved drive's outcome failed" in r.getMessage()]
    assert len(said) == 1 and said[0].exc_info is not None, caplog.text  # logged with its traceback
    monkeypatch.undo()
    await sim.wait_stopped(5.0)


async def test_the_blocks_own_exception_goes_on_with_the_exit_failure_noted(tcp_sim, monkeypatch):
    sim = tcp_sim
    rig = open_rig(sim, LIMITS)
    with pytest.raises(KeyError, match="the run's own failure") as raised:
        async with rig:
            await at_speed(rig)
            monkeypatch.setattr(Starver, "due", starver_bug)
            t_exit = time.monotonic()
            raise KeyError("the run's own failure")
    for dev in (1, 2):
        assert stopped_since(sim, dev, t_exit), (dev, sim.models[dev].control_words)
    notes = getattr(raised.value, "__notes__", [])
    assert notes == [
        "then the drives' exit failed: RuntimeError('starver bookkeeping bug') (logged); both drives stopped"
    ]
    monkeypatch.undo()
    await sim.wait_stopped(5.0)


async def test_a_released_rig_whose_poll_died_is_stopped_not_left_running(tcp_sim, monkeypatch):
    """The poll task ends on an exception outside its polls (its pacing): the drives went
    unwatched since, so the release does not leave them running: stopped, the crash raised (a
    DriveError naming it, as a command's boundary catches it; the bug its cause)."""
    sim = tcp_sim
    rig = open_rig(sim, LIMITS)

    async def pace_bug(self):
        raise RuntimeError("pace bug")

    with pytest.raises(DriveError, match=r"poll crashed \(RuntimeError\('pace bug'\)\)") as raised:
        async with rig:
            await at_speed(rig)
            monkeypatch.setattr(PollPace, "next_poll", pace_bug)
            t_dead = time.monotonic()
            rig.release()
            while not rig._poll_task.done():
                assert time.monotonic() - t_dead < 2.0, "the poll did not meet the bug"
                await asyncio.sleep(0.01)
    assert isinstance(raised.value.__cause__, RuntimeError)
    for dev in (1, 2):
        assert stopped_since(sim, dev, t_dead), (dev, sim.models[dev].control_words)
    monkeypatch.undo()
    await sim.wait_stopped(5.0)


async def test_a_failure_while_a_starved_drive_is_awaited_stops_the_other_at_once(tcp_sim, monkeypatch, caplog):
    """The spin drive ignores the stop (taken and ignored) and is being starved when the block
    ends; the exit's wait for its outcome fails on its second tick: the orbit drive gets the
    exit's stop word then, before the starving's end, and the exception surfaces. (The spin
    drive, not addressed while starved, closes unread as after a cancel: its watchdog stops it.)"""
    sim = tcp_sim
    caplog.set_level(logging.WARNING, logger="drives")
    real_write, real_tick, ticks = sim.models[1].write, way_out.first_set, []

    def ignore_stops(address, values):
        if address not in (CW, REF):
            real_write(address, values)

    async def tick_then_bug(tick, timeout):
        ticks.append(time.monotonic())
        if len(ticks) > 1:
            raise RuntimeError("tick bug")
        return await real_tick(tick, timeout=timeout)

    rig = open_rig(sim, LIMITS)
    with pytest.raises(RuntimeError, match="tick bug"):
        async with rig:
            await at_speed(rig)
            monkeypatch.setattr(sim.models[1], "write", ignore_stops)
            await rig.stop(wait=False)
            await sim.wait_for(lambda: "trips fault 7510" in caplog.text, 3.0, "the starving decided")
            monkeypatch.setattr(way_out, "first_set", tick_then_bug)
            t_exit, due = time.monotonic(), rig._poll.starver.due()
    stops = [t for t, cw in sim.models[2].control_words if t >= t_exit and cw == CW_RAMP_STOP]
    assert stops and due is not None and stops[0] < due, (stops, due)  # before the starving's end
    assert len(ticks) == 2 and "closing in up to" in caplog.text  # the wait had begun
    monkeypatch.undo()


async def test_a_released_rig_whose_exit_warning_fails_is_stopped_not_left_running(tcp_sim, monkeypatch):
    """The release's warning (what stops the drives once nobody polls them) fails to be worded: the
    exit is not a clean one, so the drives are not left running: stopped, the exception raised."""
    sim = tcp_sim
    rig = open_rig(sim, LIMITS)

    def words_bug(drives):
        raise TypeError("watchdog words bug")

    with pytest.raises(TypeError, match="watchdog words bug"):
        async with rig:
            await at_speed(rig)
            monkeypatch.setattr(rig_module, "watchdog_words", words_bug)
            rig.release()
            t_exit = time.monotonic()
    for dev in (1, 2):
        assert stopped_since(sim, dev, t_exit), (dev, sim.models[dev].control_words)
    monkeypatch.undo()
    await sim.wait_stopped(5.0)
