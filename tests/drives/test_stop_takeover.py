"""An emergency stop (OFF3) asked while a ramp stop (OFF1) is under way takes it over
(drives/stop.py StopSender): the drive that already took OFF1 gets OFF3 before the
silent drive's retries and before anyone's zero reference. On the simulator's drives
over real Modbus (TCP, RTU on a pty); the orbit drive is made silent by the test (the
simulator can silence only the whole link), the writes are read from the drive models."""

from __future__ import annotations

import asyncio
import time

import pytest
from support.drives_testkit import CW_EMERGENCY, CW_RAMP_STOP, CW_RUN, RPM, SimDrives, open_rig

from drives.drive import Drive
from drives.errors import DriveError, DriveTimeoutError
from drives.limits import DriveLimits
from drives.link import ModbusLink
from drives.pair import drive_names
from drives.stop import StopSender
from orbitrig.run.safe_stop import stop_drives

pytestmark = pytest.mark.timeout(60)

CW, REF = 0, 1  # register addresses


def record_writes(sim: SimDrives, dev: int, monkeypatch) -> list[tuple[float, int, int]]:
    """(wall s, address, first value) of every write the drive model `dev` executes from now on."""
    model, writes = sim.models[dev], []
    real = model.write

    def write(address, values):
        real(address, values)
        writes.append((time.monotonic(), address, values[0]))

    monkeypatch.setattr(model, "write", write)
    return writes


def silence(sim: SimDrives, dev: int, monkeypatch) -> list[float]:
    """Drive `dev` answers nothing from now on; returns the wall times of the requests it ignored."""
    gate, ignored = sim.endpoint._gate, []
    real = gate.admit

    def admit(dev_id):
        if dev_id == dev:
            ignored.append(time.monotonic())
            return False
        return real(dev_id)

    monkeypatch.setattr(gate, "admit", admit)
    return ignored


@pytest.fixture(autouse=True)
def _running(sim: SimDrives) -> None:
    for dev in (1, 2):
        sim.models[dev].write(CW, [CW_RUN])


def show(seq: list[tuple[int, int]]) -> str:
    """The writes `[(address, value)]` as 'CW 0x047e, REF 0, ...'."""
    return ", ".join(f"CW {v:#06x}" if a == CW else f"REF {v}" for a, v in seq)


async def _open(sim: SimDrives, timeout: float) -> tuple[ModbusLink, list[Drive]]:
    link = ModbusLink(sim.url, timeout=timeout, names=drive_names(1, 2))
    await link.connect()
    return link, [Drive(link, 1, "spin", bidirectional=False), Drive(link, 2, "orbit", bidirectional=True)]


async def test_stop_emergency_asked_during_a_ramp_stop_reaches_the_answering_drive_at_once(sim, monkeypatch):
    """OFF1 has reached the spin drive, the silent orbit drive's OFF1 is on the link, then
    OFF3 is asked. Request timeout 0.15 s: before the fix the spin drive got OFF3 only once
    the whole ramp stop was done (orbit retries, zero references), >= 0.9 s later."""
    spin_writes = record_writes(sim, 1, monkeypatch)
    orbit_tries = silence(sim, 2, monkeypatch)
    link, drives = await _open(sim, timeout=0.15)
    async with link:
        stops = StopSender(drives)
        ramp = stops.send()
        await sim.wait_for(lambda: sim.regs(1)["CW"] == CW_RAMP_STOP, 3, "OFF1 at the spin drive")
        t_asked = time.monotonic()
        emergency = stops.send(emergency=True)
        results = await asyncio.gather(ramp, emergency)
    seq = [(a, v) for _, a, v in spin_writes]
    off3 = next((t for t, a, v in spin_writes if (a, v) == (CW, CW_EMERGENCY)), None)
    assert off3 is not None, show(seq)
    assert off3 - t_asked < 0.4, f"the spin drive got OFF3 {off3 - t_asked:.3f} s after it was asked: {show(seq)}"
    tries_before = sum(t < off3 for t in orbit_tries)
    assert tries_before == 1, f"{tries_before} requests to the silent drive before the spin drive's OFF3"
    # both stops' words before any zero reference: OFF1, OFF3 (taken over), OFF3 (the emergency stop), REF 0
    assert seq == [(CW, CW_RAMP_STOP), (CW, CW_EMERGENCY), (CW, CW_EMERGENCY), (REF, 0)], show(seq)
    for errors in results:  # each stop: the silent drive missed its word, the spin drive did not
        assert [e.drive for e in errors] == [2] and isinstance(errors[0], DriveTimeoutError), errors
    assert sim.regs(1)["CW"] == CW_EMERGENCY and sim.regs(1)["REF"] == 0


async def test_stop_emergency_asked_during_a_ramp_stops_zero_references_goes_before_the_rest(sim, monkeypatch):
    """OFF3 asked once the ramp stop has reached its zero references (the spin drive's REF 0
    written, the silent orbit drive's on the link). Request timeout 0.25 s: the spin drive gets
    OFF3 after that one request, not after the orbit drive's two REF retries as well (>= 0.75 s)."""
    spin_writes = record_writes(sim, 1, monkeypatch)
    orbit_tries = silence(sim, 2, monkeypatch)
    link, drives = await _open(sim, timeout=0.25)
    async with link:
        stops = StopSender(drives)
        ramp = stops.send()
        await sim.wait_for(lambda: any(a == REF for _, a, _ in spin_writes), 5, "the spin drive's zero reference")
        t_ref = next(t for t, a, _ in spin_writes if a == REF)
        t_asked = time.monotonic()
        emergency = stops.send(emergency=True)
        await asyncio.gather(ramp, emergency)
    seq = [(a, v) for _, a, v in spin_writes]
    off3 = next((t for t, a, v in spin_writes if (a, v) == (CW, CW_EMERGENCY)), None)
    assert off3 is not None, show(seq)
    # one request's timeout and a loaded machine's scheduling; the retries as well would be >= 0.75 s
    assert off3 - t_asked < 0.7, f"the spin drive got OFF3 {off3 - t_asked:.3f} s after it was asked: {show(seq)}"
    ignored = sum(t_ref < t < off3 for t in orbit_tries)
    # 1: the orbit drive's REF 0 already on the link waits out its timeout; 0: the emergency was taken
    # before the ramp put it there (a loaded machine); never its retries as well
    assert ignored <= 1, f"{ignored} requests to the silent drive between the spin drive's REF 0 and its OFF3"
    assert seq == [(CW, CW_RAMP_STOP), (REF, 0), (CW, CW_EMERGENCY), (REF, 0)], show(seq)


async def test_an_abort_while_the_ramp_stops_words_go_out_takes_them_over(sim, monkeypatch):
    """`orbitrig.run.safe_stop.stop_drives` (a second signal on `drives stop`, `run --hold`,
    calibrate): an abort while the ramp stop's words are still going out (the silent orbit
    drive's tries) has the emergency stop take the ramp stop over, as `stop_now` does. Request
    timeout 0.25 s: before the fix the spin drive got OFF3 only once the ramp stop was done
    (the orbit drive's retries and both zero references), about 1.3 s after the abort."""
    limits = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM)
    async with open_rig(sim, limits, timeout=0.25, comm_loss_timeout=5.0) as rig:  # no watchdog trip here
        await rig.set_speeds(1000 * RPM, -500 * RPM)
        await rig.wait_settled(hold=0.05, timeout=10.0)
        spin_writes = record_writes(sim, 1, monkeypatch)
        silence(sim, 2, monkeypatch)
        aborted = asyncio.Event()
        stopping = asyncio.ensure_future(stop_drives(rig, aborted, emergency=False, timeout=5.0))
        await sim.wait_for(lambda: sim.regs(1)["CW"] == CW_RAMP_STOP, 3, "OFF1 at the spin drive")
        t_asked = time.monotonic()
        aborted.set()
        with pytest.raises(DriveError, match="orbit"):  # the silent drive took no stop
            await stopping
        monkeypatch.undo()  # the orbit drive answers again: the exit's stop reaches it
    seq = [(a, v) for _, a, v in spin_writes]
    off3 = next((t for t, a, v in spin_writes if (a, v) == (CW, CW_EMERGENCY)), None)
    assert off3 is not None, show(seq)
    assert off3 - t_asked < 0.6, f"the spin drive got OFF3 {off3 - t_asked:.3f} s after the abort: {show(seq)}"
