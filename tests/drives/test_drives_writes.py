"""Writes that must not half-happen: the RESET edge, all-or-nothing parameters,
idempotent writes retried across a lost frame. Against the simulator's drives;
every test ends by reading the drives' own registers.
"""

from __future__ import annotations

import asyncio
import logging

import pytest
from support.drives_testkit import CW_RAMP_STOP, CW_RUN, RPM, open_rig

from drives.errors import DriveExceptionResponse, DriveTimeoutError
from drives.limits import DriveLimits
from sim import drive_registers as sim_registers

pytestmark = pytest.mark.timeout(30)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM)
CW_RESET = 0x04F6
SW_TRIPPED, SW_RDY_REF = 0x08, 0x04


async def test_reset_clears_a_fault_when_the_drive_still_holds_reset_1(sim):
    """A previous client died between 0x04F6 and 0x0476: CW holds RESET = 1."""
    spin = sim.models[1]
    spin.inject_fault(4210)
    spin.write(0, [CW_RESET])  # the dead client's first reset write (cause still active)
    spin.clear_fault_cause(4210)  # the cause has gone since
    assert sim.regs(1)["CW"] == CW_RESET and sim.regs(1)["FAULT"] == 4210
    async with open_rig(sim, LIMITS) as r:
        await r.reset_faults()  # a reset of 0x04F6, 0x0476 would make no edge here
        assert sim.regs(1)["FAULT"] == 0 and not sim.regs(1)["SW"] & SW_TRIPPED
        assert sim.regs(1)["CW"] == 0x0476
        await r.set_speeds(600 * RPM, 0.0)  # and it runs again
        await r.wait_settled(hold=0.05, timeout=5)
    assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RAMP_STOP
    await sim.wait_stopped()


async def test_refused_configure_changes_nothing(sim):
    before = [sim.models[dev].read(100, 6) for dev in (1, 2)]
    async with open_rig(sim, LIMITS, comm_loss_timeout=None) as r:
        # ACCEL/DECEL valid, AT_SETPOINT_BAND 4000 rpm outside the drive's range:
        # one write-multiple, refused as a whole
        with pytest.raises(DriveExceptionResponse) as info:
            await r.spin.configure(accel_time=2.0, decel_time=3.0, at_setpoint_band=4000 * RPM)
        assert info.value.exception_code == 3
        assert "registers 102..105 (ACCEL_TIME .. AT_SETPOINT_BAND)" in str(info.value)
        assert [sim.models[dev].read(100, 6) for dev in (1, 2)] == before
        # a valid one goes through, gaps keeping their values
        params = await r.spin.configure(accel_time=2.0, at_setpoint_band=7 * RPM)
        assert params.accel_time == pytest.approx(2.0)
        assert sim.models[1].read(102, 4) == [20, before[0][3], before[0][4], 7]
    assert sim.regs(1)["ACT"] == sim.regs(2)["ACT"] == 0


async def test_configure_survives_a_lost_frame_on_its_read(sim):
    """The parameters a write keeps are read first, retried as every read but the poll's: one lost
    frame there failed the rig's opening (a busy host), though each other request of it is retried."""
    from drives.drive import Drive
    from drives.link import ModbusLink

    async with ModbusLink(sim.url, timeout=0.3) as link:
        spin = Drive(link, 1, "spin", bidirectional=False)
        sim.endpoint.drop_next(1)  # the read of configure's range goes unanswered once
        params = await spin.configure(accel_time=2.0)
    assert params.accel_time == pytest.approx(2.0) and link.retries == 1
    assert sim.models[1].read(sim_registers.ACCEL_TIME, 1) == [20]


def _outage_on_first_write(sim, link, address: int, duration: float) -> list[float]:
    """Make the endpoint drop every request for `duration` s from the first write
    to `address` (the frame carrying it is lost). Returns [time it started].

    The outage starts as that write's frame goes on the line (the link held), not when
    the write asks for the link: a poll's read holding the link then would meet the
    outage instead, and on a loaded machine the write would go out after it."""
    loop = asyncio.get_running_loop()
    request, started = link._request, []

    def outage_then(call):
        async def lossy(client):
            started.append(loop.time())
            sim.endpoint.set_unresponsive(True)
            loop.call_later(duration, sim.endpoint.set_unresponsive, False)
            return await call(client)

        return lossy

    async def request_with_outage(device_id, span, function_code, call, *more):
        if not started and span[0] == address and function_code in (6, 16):
            call = outage_then(call)
        return await request(device_id, span, function_code, call, *more)

    link._request = request_with_outage
    return started


async def test_speed_command_survives_a_lost_frame(sim, caplog):
    caplog.set_level(logging.WARNING, logger="drives")
    async with open_rig(sim, LIMITS) as r:
        started = _outage_on_first_write(sim, r.link, sim_registers.REF, 0.15)  # < 2 request timeouts
        await r.set_speeds(900 * RPM, -300 * RPM)
        await r.wait_settled(hold=0.05, timeout=5)
        assert started and r.link.retries >= 1
        assert "spin (id 1) REF (1) write: no answer" in caplog.text and "retry 1 of 2" in caplog.text
        assert sim.regs(1)["REF"] == 6000 and sim.regs(2)["REF"] == -2000
        for dev in (1, 2):
            assert sim.regs(dev)["CW"] == CW_RUN and sim.regs(dev)["FAULT"] == 0
        assert r.state.link_ok
    assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RAMP_STOP
    await sim.wait_stopped()


async def test_long_outage_fails_the_command_and_both_drives_stop(sim):
    async with open_rig(sim, LIMITS) as r:
        # the orbit REF write meets a 1.2 s outage (> 3 tries x 0.1 s and the drives'
        # 0.5 s watchdog): the spin drive is running by then
        spin_started = asyncio.Event()

        orig = r.orbit.write_reference

        async def orbit_ref_in_outage(raw, **kw):
            if not spin_started.is_set():  # the first orbit REF write: the speed command
                spin_started.set()
                sim.endpoint.set_unresponsive(True)
                asyncio.get_running_loop().call_later(1.2, sim.endpoint.set_unresponsive, False)
            await orig(raw, **kw)

        r.orbit.write_reference = orbit_ref_in_outage
        with pytest.raises(DriveTimeoutError, match=r"orbit drive \(id 2\), register REF"):
            await r.set_speeds(1500 * RPM, 600 * RPM)
        assert spin_started.is_set() and r.link.retries >= 2
        assert sim.regs(1)["SW"] & SW_RDY_REF == 0  # the running spin drive was stopped
        assert sim.regs(2)["CW"] != CW_RUN
        await sim.wait_for(lambda: not sim.endpoint.unresponsive, 3, "outage over")
    # link back: the exit's stop reached both
    assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RAMP_STOP
    await sim.wait_stopped()


@pytest.mark.parametrize("sim", ["rtu"], indirect=True)
async def test_a_silent_drive_delays_the_others_stop_by_one_timeout_only(sim):
    """Device id 3 is not on the RS-485 line (no answer): its stop word is retried
    only after the spin drive has had its own."""
    from drives.drive import Drive
    from drives.link import ModbusLink
    from drives.stop import send_stop

    sim.models[1].write(0, [CW_RUN])
    loop = asyncio.get_running_loop()
    async with ModbusLink(sim.url, timeout=0.2) as link:
        silent = Drive(link, 3, "orbit", bidirectional=True)
        spin = Drive(link, 1, "spin", bidirectional=False)
        t0 = loop.time()
        task = asyncio.create_task(send_stop([silent, spin]))
        await sim.wait_for(lambda: sim.regs(1)["CW"] == CW_RAMP_STOP, 3, "spin stop word")
        took = loop.time() - t0
        errors = await task
    assert took < 0.55, took  # one timeout (+ line settling), not 3 tries x 0.2 s
    assert [e.drive for e in errors] == [3] and isinstance(errors[0], DriveTimeoutError)
    # the silent drive's CW and zero REF: 1 try each, then 2 more (the second counted by the link)
    assert link.retries == 2
    assert sim.regs(1)["CW"] == CW_RAMP_STOP and sim.regs(1)["ACT"] == 0
