"""An emergency stop (OFF3: an abort's, an operator's) reaches a drive whose comm-loss watchdog is
being starved because it ran on through the ramp stop (drives/starve.py): its emergency ramp is
ten times faster than the ramp stop its watchdog's fault 7510 brings. The word goes through for
that stop only; a drive that took it is read while it slows in its emergency ramp (its standstill
seen), one that refuses it, or takes it and runs on, is starved again, so its watchdog still trips it. On the simulator's drives over real
Modbus (TCP, RTU on a pty); the drive's disobedience alone is the test's."""

from __future__ import annotations

import logging
import time

import pytest
from support.drives_testkit import PARAM, RPM, SimDrives, open_rig, set_parameter

from drives import registers as R
from drives.errors import DriveError
from drives.limits import DriveLimits
from drives.starve import MARGIN_S
from sim.drive_registers import COMM_LOSS_FAULT, DriveModbusException

pytestmark = pytest.mark.timeout(60)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM)
CW, REF = 0, 1  # register addresses
POLL_S, WATCHDOG_S = 0.05, 0.5  # open_rig's


def disobey(sim: SimDrives, dev: int, monkeypatch, *, off3: bool | None) -> dict[int, list[float]]:
    """From now on drive `dev` takes every CW and REF write and ignores it (`off3`: it obeys the
    emergency stop word, OFF3; False: refuses that one with exception 03; None: takes and ignores it
    too); returns the monotonic s of every request each drive receives from now on."""
    model, real = sim.models[dev], sim.models[dev].write

    def write(address, values):
        if address == CW and list(values) == [R.CW_EMERGENCY_STOP]:
            if off3 is False:
                raise DriveModbusException(0x03, "refused by the test")
            if off3:
                real(address, values)
        elif address not in (CW, REF):
            real(address, values)

    monkeypatch.setattr(model, "write", write)
    times: dict[int, list[float]] = {1: [], 2: []}
    for d, m in sim.models.items():
        note = m.note_request

        def noted(d=d, note=note):
            times[d].append(time.monotonic())
            note()

        monkeypatch.setattr(m, "note_request", noted)
    return times


async def _starved(sim: SimDrives, rig, monkeypatch, caplog, *, off3: bool | None) -> dict[int, list[float]]:
    """Both drives at speed, the spin drive runs on through the ramp stop: returns once it is starved."""
    await rig.set_speeds(1000 * RPM, -500 * RPM)
    await rig.wait_settled(hold=0.05, timeout=10.0)
    times = disobey(sim, 1, monkeypatch, off3=off3)
    await rig.stop(wait=False)  # OFF1: the orbit drive takes it, the spin drive runs on
    await sim.wait_for(lambda: "trips fault 7510" in caplog.text, 3.0, "the starving decided")
    assert sim.regs(1)["CW"] == R.CW_RUN and sim.regs(1)["FAULT"] == 0
    return times


async def test_an_emergency_stop_reaches_a_drive_whose_watchdog_is_starved(slow_drives, monkeypatch, caplog):
    """The spin drive ignored the ramp stop and is starved (a long watchdog, 3 s: starved for 3.6 s);
    the emergency stop asked then goes to it (no delivery error) and it stops in its emergency ramp
    (about 0.05 s wall here), not after its watchdog's trip and slow 7510 ramp. The poll reads it in
    that ramp, so `stop(wait=True)` returns at its standstill (its default wait, about 2.3 s, is
    outlasted by the starving) with no fault, and the exit does not wait for the starving's end."""
    sim = slow_drives
    caplog.set_level(logging.WARNING, logger="drives")
    async with open_rig(sim, LIMITS, comm_loss_timeout=3.0) as rig:
        await _starved(sim, rig, monkeypatch, caplog, off3=True)
        t_off3 = time.monotonic()
        await rig.stop(emergency=True)
        waited = time.monotonic() - t_off3
        assert rig.stop_errors == [] and rig.stop_sent == "emergency stop (OFF3)"
        spin = rig.state.spin
        assert spin is not None and spin.stopped and spin.time > t_off3 and not spin.tripped
        assert sim.regs(1)["CW"] == R.CW_EMERGENCY_STOP and sim.regs(1)["FAULT"] == 0
        with pytest.raises(DriveError, match=r"spin drive \(id 1\).*found running"):  # its defiance: the failure
            rig.check()
        monkeypatch.undo()
        t_exit = time.monotonic()
    assert waited < 0.5, f"the stop's wait took {waited:.2f} s"
    assert time.monotonic() - t_exit < 1.0, "the exit waited for the starving's end"
    assert sim.models[1].comm_lost_after is None  # never tripped by its watchdog
    assert "its watchdog starved, the emergency stop goes to it" in caplog.text
    outcome = [r.getMessage() for r in caplog.records if "after it took the emergency stop" in r.getMessage()]
    assert len(outcome) == 1 and "stopped by its emergency ramp" in outcome[0], outcome


@pytest.mark.parametrize("slow_drives", ["tcp"], indirect=True)  # on RTU the stalled answer times out instead
async def test_a_drive_read_late_in_its_emergency_ramp_is_not_starved_again(slow_drives, monkeypatch, caplog):
    """The spin drive (DECEL_TIME 15 s: its emergency ramp from 1000 rpm 0.5 s, about 0.17 s wall) took
    the emergency stop let through to it; the first read in that ramp is answered turning (ACT nonzero,
    SW OFF_3_STA 0), then the host is busy for 0.8 s (the whole process stalls, the answer is handled
    past its bound: the OFF3 + 0.5 s + two polls + the request timeout, 0.7 s). Its speed read is judged
    as of the poll's start, where that ramp puts it, not by when the answer was handled: it is read on,
    and the stop returns at its standstill."""
    sim = slow_drives
    set_parameter(sim.models[1], PARAM["DECEL_TIME"], 150)
    caplog.set_level(logging.WARNING, logger="drives")
    async with open_rig(sim, LIMITS, comm_loss_timeout=3.0) as rig:
        times = await _starved(sim, rig, monkeypatch, caplog, off3=True)
        model, answer = sim.models[1], sim.models[1].read
        stalled: list[int] = []  # raw ACT of the answer the host handled late
        ended: list[float] = []  # time.time() and monotonic s at the stall's end

        def read(address, count):
            words = answer(address, count)
            if not stalled and address == CW and count >= 5 and words[CW] == R.CW_EMERGENCY_STOP and words[4]:
                stalled.append(words[4])
                time.sleep(0.8)  # the host busy: nothing in this process runs, the rig's poll included
                ended.extend((time.time(), time.monotonic()))
            return words

        monkeypatch.setattr(model, "read", read)
        t_off3 = time.monotonic()
        await rig.stop(emergency=True)
        waited = time.monotonic() - t_off3
        assert rig.stop_errors == [] and stalled and 0 < stalled[0] < 6667, stalled  # read turning, slowing
        spin = rig.state.spin
        assert spin is not None and spin.stopped and not spin.tripped
        monkeypatch.undo()
    # the stall and then its standstill (~1 s idle); starved again, the wait ran out at 2.95 s
    assert 0.8 <= waited < 2.4, f"the stop's wait took {waited:.2f} s"
    assert sim.models[1].comm_lost_after is None  # never starved again: its watchdog never tripped
    assert "not slowing in its emergency ramp" not in caplog.text
    # the late answer was handled, not timed out: no failed poll of the spin drive logged before its
    # next request (a read timed out at the stall's end is logged before the link takes another);
    # a later read timed out on loaded cores (0.1 s) is not the test's
    wall, mono = ended
    following = min(t for t in times[1] if t > mono) - mono + wall
    failed = [r.getMessage() for r in caplog.records if wall <= r.created <= following]
    assert not [m for m in failed if m.startswith("drive poll failed") and "spin drive (id 1)" in m], failed


async def test_a_drive_taking_the_emergency_stop_and_running_on_is_starved_again(tcp_sim, monkeypatch, caplog):
    """The spin drive answers the emergency stop word and ignores it: the first read after it shows it
    still operation enabled, so it is starved again from that read (its reads fed its watchdog only
    while nothing showed it defying the OFF3) and its watchdog trips it half a second later."""
    sim = tcp_sim
    caplog.set_level(logging.WARNING, logger="drives")
    async with open_rig(sim, LIMITS) as rig:
        times = await _starved(sim, rig, monkeypatch, caplog, off3=None)
        t_off3 = time.monotonic()
        await rig.stop(emergency=True, wait=False)
        assert rig.stop_errors == []
        await sim.wait_for(lambda: "not slowing in its emergency ramp" in caplog.text, 1.0, "starved again")
        await sim.wait_for(lambda: sim.regs(1)["FAULT"] == COMM_LOSS_FAULT, 3.0, "fault 7510 at the spin drive")
        await sim.wait_for(lambda: "read again after" in caplog.text, 3.0, "the starved drive read again")
        monkeypatch.undo()
    fed = [t for t in times[1] if t_off3 <= t <= sim.models[1].comm_lost_after]
    assert 2 <= len(fed) <= 4, fed  # the OFF3, its zero REF at most, the read that found it running on
    assert sim.models[1].comm_lost_after - t_off3 < 3 * POLL_S
    outcome = [r.getMessage() for r in caplog.records if "read again after" in r.getMessage()]
    assert len(outcome) == 1 and "tripped by its comm-loss watchdog" in outcome[0], outcome


async def test_a_drive_defying_the_emergency_stop_too_is_starved_again(sim, monkeypatch, caplog):
    """The spin drive refuses the emergency stop word (exception 03): the word was tried (the
    refusal names register CW, not 'not sent'); the request fed its watchdog, so the starving
    resumes from it: no request reaches it until its watchdog trips 7510 half a second later,
    not the emergency stop pressed again either (one attempt: presses again and again would keep
    its watchdog fed)."""
    caplog.set_level(logging.WARNING, logger="drives")
    async with open_rig(sim, LIMITS) as rig:
        times = await _starved(sim, rig, monkeypatch, caplog, off3=False)
        t_off3 = time.monotonic()
        with pytest.raises(DriveError, match=r"spin drive \(id 1\), register CW") as refused:
            await rig.stop(emergency=True, wait=False)
        assert "not sent" not in str(refused.value)
        tried = [t for t in times[1] if t >= t_off3]
        assert tried, "the emergency stop word never reached the starved spin drive"
        with pytest.raises(DriveError, match=r"spin drive \(id 1\), register CW \(0\): not sent: its comm-loss"):
            await rig.stop(emergency=True, wait=False)  # pressed again: one attempt only, its watchdog not fed
        await sim.wait_for(lambda: sim.regs(1)["FAULT"] == COMM_LOSS_FAULT, 3.0, "fault 7510 at the spin drive")
        t_trip = sim.models[1].comm_lost_after + WATCHDOG_S
        await sim.wait_for(lambda: "read again after" in caplog.text, 3.0, "the starved drive read again")
        t_read = min(t for t in times[1] if t > t_trip)
        monkeypatch.undo()
    assert sim.models[1].comm_lost_after == pytest.approx(max(tried), abs=0.05)  # its last request: the OFF3's
    starved = WATCHDOG_S + MARGIN_S + 2 * POLL_S
    assert t_read - max(tried) == pytest.approx(starved, abs=0.3), "starving did not resume after the OFF3"
    outcome = [r.getMessage() for r in caplog.records if "read again after" in r.getMessage()]
    assert len(outcome) == 1 and "tripped by its comm-loss watchdog" in outcome[0], outcome
