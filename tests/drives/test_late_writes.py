"""The writes a TCP link gave up on, and how long they may still reach their drive (drives/late.py):
two request timeouts past the last write given up; a stop's own words marked as such, RTU's not recorded."""

from __future__ import annotations

import asyncio
import logging
import time

import pytest
from support.drives_testkit import RPM, open_rig, wait_until

from drives.errors import DriveError, DriveOffCommand, DriveTimeoutError
from drives.late import LATE_TIMEOUTS, LateWrites, at_rest, watch
from drives.limits import DriveLimits
from drives.link import ModbusLink
from sim import drive_registers as sim_registers

pytestmark = pytest.mark.timeout(30)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM, min_ratio=None, max_ratio=1.0)


def test_a_write_given_up_is_open_for_two_timeouts_past_the_last_one_given_up():
    late = LateWrites(timeout=0.1)
    assert late.window == pytest.approx(LATE_TIMEOUTS * 0.1) and late.until([1, 2]) is None
    late.note(1, 1, [0x0FA0])
    first = late.until([1])
    assert first is not None and 0.15 < first - time.monotonic() <= 0.2
    assert late.until([2]) is None  # another drive's writes are its own
    time.sleep(0.05)
    late.note(1, 0, [0x047F])  # the path still holds requests: the first stays open as long
    given = late.open([1])
    assert [g.said() for g in given] == ["REF (1) = 0x0FA0", "CW (0) = 0x047F"]
    assert given[0].until == given[1].until > first
    assert late.open([1], at=given[1].until) == []  # closed at its end


async def test_a_tcp_write_given_up_is_recorded_a_stops_as_one(sim):
    """Before: a stop's write given up was not recorded (a late stop word that stopped the next
    start was blamed on another client: tests/drives/test_late_stop_after_start.py)."""
    async with open_rig(sim, LIMITS, comm_loss_timeout=2.0) as r:
        sim.endpoint.set_unresponsive(True)
        given, starts = [], []
        for urgent in (True, False):  # each looked at at once: the poll's reads fail between them
            try:
                await r.link.write(1, 1, [0], retries=0, urgent=urgent)
            except Exception:  # noqa: BLE001 - the timeout is what is wanted
                pass
            given += [(g.said(), g.stop) for g in r.link.late.open([1])[-1:]]
            starts += [g.stop for g in r.link.late.starts([1])]
        sim.endpoint.set_unresponsive(False)
        tcp = sim.kind == "tcp"
        assert given == ([("REF (1) = 0x0000", True), ("REF (1) = 0x0000", False)] if tcp else [])
        assert starts == ([False] if tcp else [])  # a stop's is not a start's: no wait for it
        st = await r.spin.read_status()
        assert at_rest(st) and st.asked < st.time


async def test_the_exits_watch_ends_a_request_timeout_after_the_window_and_two_reads(tcp_sim, caplog):
    """A drive read running to the end (its stop not taken: here a stop that sends nothing): the
    watch gives up, said as an error, at the window's end + two intervals + one request timeout
    (before: + the window again, two timeouts)."""
    async with open_rig(tcp_sim, LIMITS, comm_loss_timeout=2.0) as r:
        await r.set_speeds(300 * RPM, 150 * RPM)
        late, stops = LateWrites(timeout=0.5), []  # window 1.0 s

        async def stop() -> list[DriveError]:
            stops.append(time.monotonic())
            return []

        late.note(1, 0, [0x047F])
        t0 = time.monotonic()
        errors = await watch((r.spin, r.orbit), late, stop, "ramp stop (OFF1)", 0.05)
        took = time.monotonic() - t0
    assert 1.0 + 0.1 + 0.5 - 0.05 < took < 2.0, took  # 1.6 s and a read; before: 2.1 s and a read
    assert stops  # the drive read running while the write may still arrive: the stop again
    assert any("not read stopping" in m for m in caplog.messages)
    assert [type(e) for e in errors] == [DriveTimeoutError], errors  # the exit raises it
    assert "after the ramp stop (OFF1)" in str(errors[0])


async def test_a_drive_run_again_once_no_write_given_up_can_arrive_is_the_polls_finding(tcp_sim, caplog):
    """A write given up before the stop, the stop's wait past its window: the spin drive run again
    at its keypad then is not said to be that write arrived late (no failure recorded, as before),
    but found running after the stop: the stop again and the failure (drives/owed.py)."""
    async with open_rig(tcp_sim, LIMITS, comm_loss_timeout=5.0) as r:
        await r.set_speeds(300 * RPM, 150 * RPM)
        r.link.late.note(1, 1, [0x0FA0])  # as the link records a write it gave up on
        await r.stop(wait=True, timeout=5)  # returns once read at rest past the window (0.2 s)
        assert r.link.late.until([1]) is None
        tcp_sim.keypad_run(1, 600.0)
        await wait_until(lambda: r._poll.failure is not None, 2.0, "the finding recorded")
        with pytest.raises(DriveError, match=r"spin drive \(id 1\).*after the stop"):
            r.check()
        await tcp_sim.wait_stopped(timeout=5.0)
    assert not any("reached it late" in m for m in caplog.messages)


@pytest.mark.parametrize("slow_drives", ["tcp"], indirect=True)
async def test_the_exits_watch_does_not_wait_out_the_ramps(slow_drives, caplog):
    """The exit from 1500 rpm after a write given up: its watch ends once both drives are read not
    running at REF 0 past the window, still ramping down (about 0.8 s here), nothing said as an error
    (before: it waited for ACT 0 until its end, and said they were not read at rest)."""
    async with open_rig(slow_drives, LIMITS, comm_loss_timeout=5.0) as r:
        await r.set_speeds(1500 * RPM, 700 * RPM)
        await r.wait_settled(hold=0.05, timeout=10.0)
        r.link.late.note(1, 1, [0x0FA0])  # as the link records a write it gave up on
    spin = slow_drives.regs(1)
    assert spin["ACT"] != 0 and spin["REF"] == 0, spin  # the exit returned during the ramp down
    assert not [r.getMessage() for r in caplog.records if r.levelno >= logging.ERROR]


async def test_an_exit_whose_watch_finds_a_drive_still_turning_raises(tcp_sim):
    """A write given up before the exit, and the spin drive run again and again at its keypad during
    the exit's watch: the watch ends with it still read running, and the exit raises that (before:
    only logged, and the command went on as if both drives had stopped)."""
    keypad_on = True

    async def keypad() -> None:
        while keypad_on:
            tcp_sim.keypad_run(1, 600.0)
            await asyncio.sleep(0.02)

    with pytest.raises(DriveError, match="not read stopping once every write given up could have arrived"):
        async with open_rig(tcp_sim, LIMITS, comm_loss_timeout=5.0) as r:
            await r.set_speeds(300 * RPM, 150 * RPM)
            r.link.late.note(1, 1, [0x0FA0])  # as the link records a write it gave up on
            task = asyncio.create_task(keypad())
    keypad_on = False
    await task
    tcp_sim.keypad_run(1, 0.0)


@pytest.mark.parametrize("given_up", [True, False])
async def test_a_drive_moved_off_its_command_names_a_write_given_up_still_open(tcp_sim, given_up):
    """The spin drive's REF changed while both run at the command (here by a second client, as a
    late REF would arrive): with a REF write to it given up and still open, the finding names that
    write beside another client or the keypad (before: another client or the keypad alone)."""
    async with open_rig(tcp_sim, LIMITS, comm_loss_timeout=2.0) as r:
        await r.set_speeds(1000 * RPM, 600 * RPM)
        await r.wait_settled(hold=0.05, timeout=5)
        if given_up:
            r.link.late = LateWrites(timeout=2.0)  # a slow path: the write open for 4 s
            r.link.late.note(1, sim_registers.REF, [10000])
        async with ModbusLink(tcp_sim.url, timeout=0.3) as other:
            await other.write(1, sim_registers.REF, [10000])  # 1500 rpm
        with pytest.raises(DriveOffCommand) as info:
            await r.wait_settled(hold=5.0, timeout=5)
        await tcp_sim.wait_stopped(timeout=5)
    words = str(info.value)
    assert "spin drive (id 1), register REF (1): was given another reference" in words, words
    late = "; or a write the link gave up on (REF (1) = 0x2710) reached it late"
    assert words.endswith(late) if given_up else late not in words, words
