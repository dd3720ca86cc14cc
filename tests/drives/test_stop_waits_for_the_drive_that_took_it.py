"""`RigDrives.stop` when one drive does not take the stop (its word refused with exception 03):
the stop goes to both, the drive that took it is waited for (its standstill, or its trip during
the stop, observed), and then the stop raises naming the drive that did not take it, its message
ending with what the other one did. It raised at once, the other drive still turning and its trip
never seen. On the simulator's drives over real Modbus (TCP, RTU on a pty), slow ramps (about
0.5 s wall from 1000 rpm); the refusal is the test's (the simulator's drives always obey), the trip
the simulator's own (overcurrent 2310)."""

from __future__ import annotations

import time

import pytest
from support.drives_testkit import RPM, SimDrives, open_rig

from drives.errors import DriveError, DriveExceptionResponse, StopTripError
from drives.limits import DriveLimits
from sim.drive_registers import DriveModbusException

pytestmark = pytest.mark.timeout(60)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM)
CW = 0  # register address


def refuse_stop_words(sim: SimDrives, dev: int, monkeypatch) -> None:
    """From now on drive `dev` answers every CW write with exception 03."""
    model, real = sim.models[dev], sim.models[dev].write

    def write(address, values):
        if address == CW:
            raise DriveModbusException(0x03, "refused by the test")
        real(address, values)

    monkeypatch.setattr(model, "write", write)


async def test_the_stop_raises_for_the_drive_that_missed_it_once_the_other_is_at_standstill(slow_drives, monkeypatch):
    sim = slow_drives
    async with open_rig(sim, LIMITS) as rig:
        await rig.set_speeds(1000 * RPM, -1000 * RPM)
        await rig.wait_settled(hold=0.05, timeout=10.0)
        refuse_stop_words(sim, 1, monkeypatch)
        t0 = time.monotonic()
        with pytest.raises(DriveExceptionResponse) as missed:
            await rig.stop()
        took = time.monotonic() - t0
        orbit_act, errors = sim.regs(2)["ACT"], [e.drive for e in rig.stop_errors]
        monkeypatch.undo()  # the exit's stop reaches the spin drive
    assert orbit_act == 0, f"raised {took:.2f} s after the stop, the orbit drive still at {orbit_act}"
    assert took > 0.2, f"raised after {took:.2f} s: the orbit drive's ramp (about 0.5 s) was not waited for"
    said = str(missed.value)
    assert said.startswith("spin drive (id 1), register CW (0): "), said
    assert said.endswith("; orbit drive (id 2), which took the stop, at standstill"), said
    assert errors == [1]


async def test_a_trip_of_the_drive_that_took_the_stop_is_observed(slow_drives, monkeypatch):
    """The orbit drive trips (overcurrent 2310, a coast stop) while ramping down on the stop the
    spin drive refused: the trip is waited for and said, the spin drive's refusal raised."""
    sim = slow_drives
    async with open_rig(sim, LIMITS) as rig:
        await rig.set_speeds(1000 * RPM, -1000 * RPM)
        await rig.wait_settled(hold=0.05, timeout=10.0)
        refuse_stop_words(sim, 1, monkeypatch)
        real = sim.models[2].write

        def trip_on_stop(address, values):  # the orbit drive takes its stop word, then trips
            real(address, values)
            if address == CW:
                sim.models[2].inject_fault(2310)

        monkeypatch.setattr(sim.models[2], "write", trip_on_stop)
        with pytest.raises(DriveError) as missed:
            await rig.stop()
        monkeypatch.undo()
        sim.models[2].clear_fault_cause(2310)
    said = str(missed.value)
    assert said.startswith("spin drive (id 1), register CW (0): "), said
    assert "; orbit drive (id 2), which took the stop, not confirmed at standstill: orbit drive (id 2)" in said, said
    assert "fault 2310" in said and "tripped during the ramp stop (OFF1)" in said, said
    assert isinstance(missed.value.__cause__, StopTripError)
