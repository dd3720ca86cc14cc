"""A drive poll task that dies on a bug outside its polls (its pacing, say: no poll catches that)
leaves nobody watching the drives: no trip would be seen, no tick comes. The waits on the poll
(`wait_settled`, the stop's wait for standstill) raise promptly a DriveError naming the crash
(chained to it) instead of running to their timeout; both drives get the stop at once; a new
speed is refused; the rig's exit still stops them and raises the crash (the DriveError, the bug its cause).

Real parts: the simulator's drives behind Modbus TCP, their comm-loss watchdog off (only a stop
word the rig sends stops them); the bug is injected (no real part produces one)."""

from __future__ import annotations

import logging
import time

import pytest
from support.drives_testkit import CW_RAMP_STOP, CW_RUN, RPM, SimDrives, open_rig

from drives.errors import DriveError
from drives.limits import DriveLimits
from drives.poll_pace import PollPace
from sim.drive_registers import COMM_LOSS_FAULT

pytestmark = pytest.mark.timeout(30)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM)
WATCHDOG_S = 3.0  # the starved drive's comm-loss timeout: the exit's wait for it would be longer


def _crash_the_poll(monkeypatch) -> None:
    """The poll's next wait for its pace raises (a bug): the poll task ends on it."""

    async def broken(self) -> None:
        raise RuntimeError("pacing bug")

    monkeypatch.setattr(PollPace, "next_poll", broken)


def defy_stops(sim: SimDrives, dev: int, monkeypatch) -> None:
    """From now on drive `dev` answers every CW and REF write as taken and ignores it."""
    model, real = sim.models[dev], sim.models[dev].write
    monkeypatch.setattr(model, "write", lambda address, values: None if address in (0, 1) else real(address, values))


def _stop_words_since(sim: SimDrives, dev: int, t0: float) -> set[int]:
    return {cw for t, cw in sim.models[dev].control_words if t >= t0}


def _names_the_crash(err: DriveError) -> None:
    assert "poll" in str(err) and "RuntimeError('pacing bug')" in str(err), err
    assert isinstance(err.__cause__, RuntimeError), repr(err.__cause__)


async def test_wait_settled_raises_the_poll_crash_at_once_and_the_drives_are_stopped(tcp_sim, monkeypatch):
    sim = tcp_sim
    rig = open_rig(sim, LIMITS, comm_loss_timeout=0.0)
    with pytest.raises(DriveError) as at_exit:  # the exit: stop sent, then the crash
        async with rig:
            await rig.set_speeds(1000 * RPM, -500 * RPM)
            await rig.wait_settled(hold=0.1, timeout=10.0)
            assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RUN
            t0 = time.monotonic()
            _crash_the_poll(monkeypatch)
            with pytest.raises(DriveError) as raised:
                await rig.wait_settled(hold=0.5, timeout=10.0)
            took = time.monotonic() - t0
            assert took < 1.0, took  # poll interval 50 ms: not the wait's 10 s timeout
            _names_the_crash(raised.value)
            for dev in (1, 2):  # the crash's own stop, before anyone unwinds
                assert _stop_words_since(sim, dev, t0) == {CW_RAMP_STOP}, (dev, sim.models[dev].control_words)
            with pytest.raises(DriveError) as refused:  # nobody would watch them: no new speed
                await rig.set_speeds(500 * RPM, 0.0)
            assert refused.value is raised.value
            assert _stop_words_since(sim, 1, t0) == {CW_RAMP_STOP}  # nothing started
            t_exit = time.monotonic()
    assert at_exit.value is raised.value
    for dev in (1, 2):  # the exit's stop as well
        assert _stop_words_since(sim, dev, t_exit) == {CW_RAMP_STOP}, (dev, sim.models[dev].control_words)
    await sim.wait_stopped(10.0)


async def test_the_stop_wait_raises_the_poll_crash_at_once(tcp_sim, monkeypatch):
    sim = tcp_sim
    rig = open_rig(sim, LIMITS, comm_loss_timeout=0.0)
    with pytest.raises(DriveError) as at_exit:  # the exit: stop sent, then the crash
        async with rig:
            await rig.set_speeds(1000 * RPM, -500 * RPM)
            await rig.wait_settled(hold=0.1, timeout=10.0)
            _crash_the_poll(monkeypatch)
            t0 = time.monotonic()
            with pytest.raises(DriveError) as raised:
                await rig.stop(wait=True, timeout=10.0)
            took = time.monotonic() - t0
            assert took < 1.0, took
            _names_the_crash(raised.value)
            assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RAMP_STOP
    assert at_exit.value is raised.value
    await sim.wait_stopped(10.0)


async def test_the_exit_does_not_wait_for_a_starved_drive_once_the_poll_has_crashed(tcp_sim, monkeypatch, caplog):
    """The rig closes while the spin drive's watchdog is being starved (it ran on through the stop:
    drives/starve.py); the exit waits for the poll to read it again (its watchdog 3 s here). The
    poll crashes during that wait: nobody will read it again, so the exit stops waiting at once
    (not at the starving's end) and raises the crash (a DriveError naming it); the drive's own
    watchdog still trips it."""
    sim = tcp_sim
    caplog.set_level(logging.WARNING, logger="drives")
    rig = open_rig(sim, LIMITS, comm_loss_timeout=WATCHDOG_S)
    with pytest.raises(DriveError) as raised:
        async with rig:
            await rig.set_speeds(1000 * RPM, -500 * RPM)
            await rig.wait_settled(hold=0.05, timeout=10.0)
            defy_stops(sim, 1, monkeypatch)
            await rig.stop(wait=False)
            await sim.wait_for(lambda: "trips fault 7510" in caplog.text, 3.0, "the starving decided")
            assert rig._poll.starver.due() is not None
            _crash_the_poll(monkeypatch)  # at its next poll, while the exit waits for the starved drive
            t_exit = time.monotonic()
    took = time.monotonic() - t_exit
    _names_the_crash(raised.value)  # a drive error, as a command's boundary catches it; the bug its cause
    assert took < 1.0, f"the exit took {took:.2f} s"  # the starving's end: about WATCHDOG_S + MARGIN_S away
    assert sim.regs(2)["CW"] == CW_RAMP_STOP
    monkeypatch.undo()
    await sim.wait_for(
        lambda: sim.regs(1)["FAULT"] == COMM_LOSS_FAULT, WATCHDOG_S + 3.0, "fault 7510 at the spin drive"
    )
    await sim.wait_stopped(10.0)
