"""A new speed is not a restart of a drive someone else stopped.

Mid-run, another Modbus client (a second terminal's `orbitrig drives stop`) stops the orbit
drive just before the run commands the next orbit speed. Before, `set_speeds` read the drive
stopped (no poll had read it yet), took it for a drive at rest and ran it up again with its full
start (REF, READY, RUN): the other client's stop was undone and the run went on as if nothing had
happened (the sweep test of it ended "completed" now and then on a busy host). And when the poll
had read it first, its stop for it was still going out as `set_speeds` read the drives, and the
start words went out after that stop. Now `set_speeds` judges the drives it read against the
command they were running at, as the poll does, and a stop the poll sends for what it found
ends the start: both drives stopped, the finding raised, no start word after the other
client's stop. The simulator's drives behind a real Modbus server, the other client a second
real Modbus connection."""

from __future__ import annotations

import asyncio

import pytest

from drives.drive import Drive
from drives.errors import DriveOffCommand
from drives.limits import DriveLimits
from drives.link import ModbusLink
from drives.stop import StopSender
from support.drives_testkit import CW_RAMP_STOP, CW_RUN, open_rig, wait_until

pytestmark = pytest.mark.timeout(60)

LIMITS = DriveLimits(max_spin=400.0, max_orbit=400.0)
STOPPED_ELSEWHERE = r"orbit drive \(id 2\), register SW \(3\): is no longer running .* another client"


async def _running(rig) -> None:
    await rig.set_speeds(200.0, 100.0)
    await rig.wait_settled(hold=0.1, timeout=10.0)


async def _other_client_stops_the_orbit_drive(url: str) -> None:
    """OFF1 to the orbit drive from a second Modbus connection."""
    async with ModbusLink(url, timeout=1.0) as other:
        await other.write(2, 0, [CW_RAMP_STOP])


def _words_after_the_other_clients_stop(sim, before: int) -> list[int]:
    words = [cw for _, cw in sim.models[2].control_words][before:]
    assert words and words[0] == CW_RAMP_STOP, [hex(cw) for cw in words]
    return words


async def test_a_drive_stopped_by_another_client_is_not_started_again_by_the_next_speed(tcp_sim):
    """The poll reads every 0.4 s: the next speed is commanded well before it reads the drive."""
    async with open_rig(tcp_sim, LIMITS, poll_interval=0.4, comm_loss_timeout=2.0) as rig:
        await _running(rig)
        polls = rig.state.polls
        await wait_until(lambda: rig.state.polls > polls, 5.0, "a poll")  # the next one 0.4 s away
        before = len(tcp_sim.models[2].control_words)
        await _other_client_stops_the_orbit_drive(tcp_sim.url)
        with pytest.raises(DriveOffCommand, match=STOPPED_ELSEWHERE):
            await rig.set_speeds(200.0, 150.0)
        words = _words_after_the_other_clients_stop(tcp_sim, before)
        assert CW_RUN not in words, [hex(cw) for cw in words]
        await asyncio.sleep(0.3)  # 7.5 s of the drives' time: a start would have reached its setpoint
        assert tcp_sim.regs(2)["REF"] == 0 and tcp_sim.rpm(2) == 0.0, tcp_sim.regs(2)
        assert tcp_sim.regs(1)["ACT"] == 0, tcp_sim.regs(1)  # both stopped


async def test_a_start_whose_read_answered_as_the_polls_stop_went_out_does_not_undo_it(tcp_sim, monkeypatch):
    """The next speed's read of the orbit drive answers (drive stopped) just as the poll, having
    read it first, asks its stop: `set_speeds` goes on while that stop goes out (the moment is
    what a real part cannot be made to hit: the read's answer is held until the stop is asked)."""
    real_send, real_read, stop_asked, speeds = StopSender.send, Drive.read_status, asyncio.Event(), []

    def send(self, *, emergency=False, **kw):
        stop_asked.set()
        return real_send(self, emergency=emergency, **kw)

    async def read_status(self, *args, **kw):
        st = await real_read(self, *args, **kw)
        if asyncio.current_task() in speeds and self.name == "orbit":
            await stop_asked.wait()  # the poll's stop for it is under way now
        return st

    async with open_rig(tcp_sim, LIMITS) as rig:
        await _running(rig)
        monkeypatch.setattr(StopSender, "send", send)
        monkeypatch.setattr(Drive, "read_status", read_status)
        before = len(tcp_sim.models[2].control_words)
        await _other_client_stops_the_orbit_drive(tcp_sim.url)
        speeds.append(asyncio.ensure_future(rig.set_speeds(200.0, 150.0)))
        with pytest.raises(DriveOffCommand, match=STOPPED_ELSEWHERE):
            await speeds[0]
        words = _words_after_the_other_clients_stop(tcp_sim, before)
        assert CW_RUN not in words, [hex(cw) for cw in words]
        await asyncio.sleep(0.3)
        assert tcp_sim.regs(2)["REF"] == 0 and tcp_sim.rpm(2) == 0.0, tcp_sim.regs(2)
