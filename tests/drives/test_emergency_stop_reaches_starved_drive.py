"""An emergency stop (OFF3: an abort's, an operator's) reaches a drive whose comm-loss watchdog is
being starved because it ran on through the ramp stop (drives/starve.py): its emergency ramp is
ten times faster than the ramp stop its watchdog's fault 7510 brings. The word goes through for
that stop only; the starving then resumes, its clock started again from that word, so a drive
that defies the OFF3 too is still tripped by its watchdog. On the simulator's drives over real
Modbus (TCP, RTU on a pty); the drive's disobedience alone is the test's."""

from __future__ import annotations

import logging
import time

import pytest
from support.drives_testkit import RPM, SimDrives, open_rig

from drives import registers as R
from drives.errors import DriveError
from drives.limits import DriveLimits
from drives.starve import MARGIN_S
from sim.drive_registers import COMM_LOSS_FAULT, DriveModbusException

pytestmark = pytest.mark.timeout(60)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM)
CW, REF = 0, 1  # register addresses
POLL_S, WATCHDOG_S = 0.05, 0.5  # open_rig's


def disobey(sim: SimDrives, dev: int, monkeypatch, *, off3: bool) -> dict[int, list[float]]:
    """From now on drive `dev` takes every CW and REF write and ignores it (`off3`: it obeys the
    emergency stop word, OFF3, else refuses that one with exception 03); returns the monotonic s of
    every request each drive receives from now on."""
    model, real = sim.models[dev], sim.models[dev].write

    def write(address, values):
        if address == CW and list(values) == [R.CW_EMERGENCY_STOP]:
            if not off3:
                raise DriveModbusException(0x03, "refused by the test")
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


async def _starved(sim: SimDrives, rig, monkeypatch, caplog, *, off3: bool) -> dict[int, list[float]]:
    """Both drives at speed, the spin drive runs on through the ramp stop: returns once it is starved."""
    await rig.set_speeds(1000 * RPM, -500 * RPM)
    await rig.wait_settled(hold=0.05, timeout=10.0)
    times = disobey(sim, 1, monkeypatch, off3=off3)
    await rig.stop(wait=False)  # OFF1: the orbit drive takes it, the spin drive runs on
    await sim.wait_for(lambda: "trips fault 7510" in caplog.text, 3.0, "the starving decided")
    assert sim.regs(1)["CW"] == R.CW_RUN and sim.regs(1)["FAULT"] == 0
    return times


async def test_an_emergency_stop_reaches_a_drive_whose_watchdog_is_starved(slow_drives, monkeypatch, caplog):
    """The spin drive ignored the ramp stop and is starved; the emergency stop asked then goes to
    it (no delivery error) and it stops in its emergency ramp (about 0.05 s wall here), not after
    its watchdog's trip and slow 7510 ramp (0.5 s + about 0.5 s): at standstill it has no fault."""
    sim = slow_drives
    caplog.set_level(logging.WARNING, logger="drives")
    async with open_rig(sim, LIMITS) as rig:
        await _starved(sim, rig, monkeypatch, caplog, off3=True)
        t_off3 = time.monotonic()
        await rig.stop(emergency=True, wait=False)
        assert rig.stop_errors == [] and rig.stop_sent == "emergency stop (OFF3)"
        assert sim.regs(1)["CW"] == R.CW_EMERGENCY_STOP
        took = await sim.wait_for(lambda: sim.regs(1)["ACT"] == 0, 3.0, "the spin drive at standstill")
        assert sim.regs(1)["FAULT"] == 0, "stopped by its watchdog's fault, not by the emergency stop"
        await sim.wait_for(lambda: "read again after" in caplog.text, 3.0, "the starved drive read again")
        with pytest.raises(DriveError):
            rig.check()
        monkeypatch.undo()
    assert took < 0.3, f"the spin drive stood still {took:.2f} s after the emergency stop"
    assert sim.models[1].comm_lost_after >= t_off3  # starved again after the OFF3: no request since
    assert "its watchdog starved, the emergency stop goes to it" in caplog.text


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
