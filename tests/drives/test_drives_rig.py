"""RigDrives against the simulator's drives over Modbus TCP and RTU on a pty.

Every failure test ends by reading the drives' own registers (the simulator
model, not drives/) to prove both are stopping.
"""

from __future__ import annotations

import asyncio
import logging
import math
import time

import pytest
from support.drives_testkit import CW_EMERGENCY, CW_RAMP_STOP, CW_RUN, PARAM, RPM, open_rig, set_parameter

from drives.errors import (
    DriveError,
    DriveExceptionResponse,
    DriveFaultError,
    DriveLimitError,
    DriveOffCommand,
)
from drives.limits import DriveLimits
from drives.link import ModbusLink
from drives.opening import params_to_write
from drives.rig import RigDrives
from sim import drive_registers as sim_registers

pytestmark = pytest.mark.timeout(30)  # a hang fails fast, with a traceback

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM, min_ratio=None, max_ratio=1.0)


def rig(sim, limits=LIMITS, **kw) -> RigDrives:
    """The test rig's drives with room for a loaded machine: 0.3 s per request and a 2 s
    watchdog (the link and the watchdog are not these tests' subject; the tests of them
    state their own timings). With 0.1 s and 0.5 s, an event loop held up half a second
    under load tripped a drive on communication loss."""
    kw.setdefault("timeout", 0.3)
    kw.setdefault("comm_loss_timeout", 2.0)
    return open_rig(sim, limits, **kw)


async def test_start_forward_with_scaling_read_from_the_drive(sim):
    set_parameter(sim.models[2], PARAM["SPEED_SCALE"], 6000)  # orbit drive: 20000 = 6000 rpm
    async with rig(sim) as r:
        await r.set_speeds(1000 * RPM, 600 * RPM)
        st = await r.wait_settled(hold=0.1, timeout=5)
        assert st.spin.actual == pytest.approx(1000 * RPM, abs=5 * RPM)
        assert st.orbit.actual == pytest.approx(600 * RPM, abs=5 * RPM)
        assert sim.regs(1)["REF"] == 6667 and sim.regs(2)["REF"] == 2000
        assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RUN
        assert sim.rpm(1) == pytest.approx(1000, abs=5) and sim.rpm(2) == pytest.approx(600, abs=5)
        assert st.spin.running and st.orbit.at_setpoint and st.spin.torque > 0
        await r.stop()
        assert r.state.stopped
    assert sim.regs(1)["ACT"] == sim.regs(2)["ACT"] == 0


async def test_the_speeds_are_returned_as_written_each_ref_rounded_to_its_count(sim):
    """REF counts 0.15 rpm at SPEED_SCALE 3000 rpm (docs/protocols/drive-modbus.md): 1000 rpm is
    written 6667 counts, 1000.05 rpm; -650 rpm -4333, -649.95 rpm; a scale of 6000 rpm doubles the step."""
    set_parameter(sim.models[2], PARAM["SPEED_SCALE"], 6000)  # orbit drive: 0.3 rpm per count
    async with rig(sim) as r:
        spin, orbit = await r.set_speeds(1000 * RPM, -650 * RPM)
        assert sim.regs(1)["REF"] == 6667 and sim.regs(2)["REF"] == -2167
        assert spin == pytest.approx(1000.05 * RPM, rel=1e-12)
        assert orbit == pytest.approx(-650.1 * RPM, rel=1e-12)
        assert spin / abs(orbit) == pytest.approx(1.538302, abs=1e-6)  # requested 1000/650 = 1.538462
        await r.stop()


async def test_reverse_whirl(sim):
    async with rig(sim) as r:
        await r.set_speeds(1200 * RPM, -900 * RPM)
        st = await r.wait_settled(hold=0.1, timeout=5)
        assert st.orbit.actual == pytest.approx(-900 * RPM, abs=5 * RPM)
        assert sim.regs(2)["REF"] == -6000  # two's complement on the wire
        assert sim.rpm(2) == pytest.approx(-900, abs=5)
        # through zero to forward whirl
        await r.set_speeds(1200 * RPM, 300 * RPM)
        await r.wait_settled(hold=0.1, timeout=5)
        assert sim.rpm(2) == pytest.approx(300, abs=5)


@pytest.mark.parametrize(
    "spin_rpm, orbit_rpm, match",
    [
        (2450, 100, "max_spin"),
        (1000, -2450, "max_orbit"),
        (1000, -1100, r"\|Omega\|/omega"),
        (-100, 0, "one way only"),
    ],
)
async def test_limits_refused_before_anything_is_written(sim, spin_rpm, orbit_rpm, match):
    async with rig(sim) as r:
        await r.set_speeds(800 * RPM, -400 * RPM)
        await r.wait_settled(hold=0.05, timeout=5)
        before = (sim.regs(1), sim.regs(2))
        with pytest.raises(DriveLimitError, match=match):
            await r.set_speeds(spin_rpm * RPM, orbit_rpm * RPM)
        await asyncio.sleep(0.1)
        after = (sim.regs(1), sim.regs(2))
        for b, a in zip(before, after):
            assert (a["CW"], a["REF"]) == (b["CW"], b["REF"]) == (CW_RUN, b["REF"])
        assert sim.rpm(1) == pytest.approx(800, abs=5)  # still running as before


async def test_drive_max_speed_is_a_limit_too(sim):
    set_parameter(sim.models[1], PARAM["MAX_SPEED"], 1500)
    async with rig(sim, DriveLimits(math.inf, math.inf)) as r:
        with pytest.raises(DriveLimitError, match=r"spin drive \(id 1\), register MAX_SPEED.*1500"):
            await r.set_speeds(1600 * RPM, 0.0)
        assert sim.regs(1)["CW"] == 0 and sim.regs(1)["REF"] == 0  # nothing sent


async def test_trip_stops_both_and_reset(sim):
    async with rig(sim) as r:
        await r.set_speeds(1500 * RPM, 900 * RPM)
        await r.wait_settled(hold=0.05, timeout=5)
        sim.models[1].inject_fault(2310)
        with pytest.raises(DriveFaultError) as info:
            await r.wait_settled(hold=0.05, timeout=5)
        err = info.value
        assert (err.drive, err.fault_code, err.register) == (1, 2310, 6)
        assert "spin drive (id 1)" in str(err) and "2310 (overcurrent)" in str(err)
        # the healthy orbit drive is ramped down by the interlock, not left turning
        assert sim.regs(2)["CW"] == CW_RAMP_STOP
        await sim.wait_stopped(timeout=3)
        assert sim.regs(1)["FAULT"] == 2310 and sim.regs(2)["FAULT"] == 0
        # a tripped drive is refused, nothing written
        with pytest.raises(DriveFaultError, match="reset"):
            await r.set_speeds(500 * RPM, 100 * RPM)
        assert sim.regs(1)["REF"] == 0
        # the cause is still there: reset refused
        with pytest.raises(DriveFaultError, match="still active") as info:
            await r.reset_faults()
        assert info.value.fault_code == 2310
        sim.models[1].clear_fault_cause()
        await r.reset_faults()
        assert sim.regs(1)["FAULT"] == 0
        await r.set_speeds(500 * RPM, 100 * RPM)
        await r.wait_settled(hold=0.05, timeout=5)
        assert sim.rpm(1) == pytest.approx(500, abs=5)


async def test_a_drive_moved_by_another_client_stops_both_as_a_trip_does(tcp_sim):
    """Another Modbus master writes the spin drive's REF while both run at the command: the poll
    finds it at another reference, ramps both drives to zero and records it (DriveOffCommand,
    naming the drive and REF); before, the drives ran on at the other client's speed. The finding
    is latched as a trip is: a new command is refused until `reset_faults` (a start must not undo
    a stop the poll made before anyone heard of it); then the drives run again."""
    async with rig(tcp_sim) as r:
        await r.set_speeds(1000 * RPM, 600 * RPM)
        await r.wait_settled(hold=0.05, timeout=5)
        async with ModbusLink(tcp_sim.url, timeout=0.3) as other:
            await other.write(1, sim_registers.REF, [10000])  # 1500 rpm (20000 = SPEED_SCALE, 3000 rpm)
        with pytest.raises(DriveOffCommand) as info:
            await r.wait_settled(hold=5.0, timeout=5)
        err = info.value
        assert (err.drive, err.register) == (1, sim_registers.REF)
        assert "spin drive (id 1), register REF (1): was given another reference" in str(err), str(err)
        assert tcp_sim.regs(2)["CW"] == CW_RAMP_STOP and tcp_sim.regs(1)["CW"] == CW_RAMP_STOP
        await tcp_sim.wait_stopped(timeout=3)
        with pytest.raises(DriveOffCommand):
            await r.set_speeds(500 * RPM, 100 * RPM)
        await asyncio.sleep(0.3)
        assert tcp_sim.rpm(1) == pytest.approx(0, abs=1) and tcp_sim.rpm(2) == pytest.approx(0, abs=1)
        await r.reset_faults()
        await r.set_speeds(500 * RPM, 100 * RPM)
        await r.wait_settled(hold=0.05, timeout=5)
        assert tcp_sim.rpm(1) == pytest.approx(500, abs=5)


async def test_a_drive_taken_to_local_control_as_the_start_returns_stops_both(tcp_sim, caplog):
    """The spin drive taken to its keypad (800 rpm) as the start returns, before any poll found
    both at the command: its REF register still holds the command and it reads AT_SETPOINT of the
    keypad's speed, but it is not under the command. The first poll read after the start confirmed
    both running finds it (SW REMOTE = 0), stops both and fails the wait at once; before, the wait
    ran to its timeout (the settle's, 60 s in a sweep) with the spin turning under the keypad, and
    earlier still it returned with the spin at 800 rpm instead of 1000. The keypad holds it: it
    refuses the stop word (exception 03), said as local control; the orbit drive is stopped."""
    caplog.set_level(logging.ERROR, logger="drives")
    async with rig(tcp_sim) as r:
        await r.set_speeds(1000 * RPM, 600 * RPM)
        tcp_sim.models[1].local_control(800.0)  # no await since the start: no poll in between
        t0 = time.monotonic()
        with pytest.raises(DriveOffCommand) as info:
            st = await r.wait_settled(hold=0.05, timeout=10.0)
            raise AssertionError(f"settled with the spin drive in local control: {st.describe()}")
        assert time.monotonic() - t0 < 1.0  # the poll's first reads (interval 0.1 s), not the timeout
        assert (info.value.drive, info.value.register) == (1, sim_registers.SW)
        assert "was taken to local control (SW REMOTE = 0" in str(info.value), str(info.value)
        assert tcp_sim.regs(2)["CW"] == CW_RAMP_STOP  # the orbit drive stopped by the network
        await tcp_sim.wait_for(lambda: tcp_sim.regs(2)["ACT"] == 0, 5, "the orbit drive at standstill")
        assert tcp_sim.regs(1)["CW"] == CW_RUN and tcp_sim.rpm(1) == pytest.approx(800.0)  # the keypad's
        said = "spin drive (id 1), register CW (0): did not take the ramp stop (OFF1, 0x047E): in local control"
        assert any(m.startswith("stop command not delivered: " + said) for m in caplog.messages), caplog.messages
        tcp_sim.models[1].hand_back()  # the operator gives it back: the rig's exit stops it
    await tcp_sim.wait_stopped(timeout=5)


async def test_cancelled_task_leaves_both_drives_stopping(sim):
    settled = asyncio.Event()

    async def session():
        async with rig(sim) as r:
            await r.set_speeds(2000 * RPM, -1500 * RPM)
            await r.wait_settled(hold=0.05, timeout=5)
            settled.set()
            await asyncio.sleep(30)

    task = asyncio.create_task(session())
    await asyncio.wait_for(settled.wait(), 10)
    task.cancel()
    await asyncio.sleep(0)
    task.cancel()  # a second cancellation must not skip the stop
    with pytest.raises(asyncio.CancelledError):
        await task
    # stopped by command at once (not by the watchdog: no fault)
    for dev in (1, 2):
        regs = sim.regs(dev)
        assert regs["CW"] == CW_RAMP_STOP and regs["FAULT"] == 0, regs
    assert abs(sim.rpm(1)) > 100  # still ramping down, along DECEL_TIME
    await sim.wait_stopped(timeout=3)


async def test_exception_in_the_block_stops_both(sim):
    with pytest.raises(RuntimeError, match="operator error"):
        async with rig(sim) as r:
            await r.set_speeds(1000 * RPM, 500 * RPM)
            await r.wait_settled(hold=0.05, timeout=5)
            raise RuntimeError("operator error")
    assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RAMP_STOP
    await sim.wait_stopped()


async def test_emergency_stop(sim):
    # DECEL_TIME 60 s: a ramp stop from 2000 rpm would take 40 s simulated, 1.6 s wall
    async with rig(sim, decel_time=60.0) as r:
        await r.set_speeds(2000 * RPM, 2000 * RPM)
        await r.wait_settled(hold=0.05, timeout=5)
        t = asyncio.get_running_loop().time()
        await r.stop(emergency=True)
        took = asyncio.get_running_loop().time() - t
        for dev in (1, 2):
            regs = sim.regs(dev)
            assert regs["CW"] == CW_EMERGENCY and not regs["SW"] & 0x20  # OFF_3_STA = 0
        assert took < 0.8  # OFF3: 10 x faster than DECEL_TIME (0.16 s wall)
    assert sim.regs(1)["ACT"] == sim.regs(2)["ACT"] == 0
    # the exit repeated the emergency stop rather than relaxing it to OFF1
    assert sim.regs(1)["CW"] == CW_EMERGENCY


async def test_ramp_times_and_parameter_write_refused_while_running(sim):
    async with rig(sim, accel_time=2.0, decel_time=1.0) as r:
        assert r.spin.params.accel_time == pytest.approx(2.0)
        assert sim.models[2].parameter(PARAM["DECEL_TIME"]) == 10
        await r.set_speeds(300 * RPM, 0.0)
        with pytest.raises(DriveExceptionResponse) as info:
            await r.spin.configure(accel_time=3.0)
        assert info.value.exception_code == 3
        assert "spin drive (id 1), register ACCEL_TIME (102)" in str(info.value)


async def test_exception_response_is_raised_not_returned(sim):
    async with ModbusLink(sim.url, timeout=0.3, names={1: "spin"}) as link:
        with pytest.raises(DriveExceptionResponse) as info:
            await link.read(1, 50, 1)
        assert info.value.exception_code == 2 and "register unknown register (50)" in str(info.value)
        with pytest.raises(DriveExceptionResponse):
            await link.write(1, 3, [0])  # SW is read-only
        assert await link.read(1, 100, 1) == [3000]  # the link is still fine


async def test_exception_to_a_multi_register_request_names_the_whole_range(sim):
    """The answer does not say which register of a range was refused: the error names them all."""
    async with ModbusLink(sim.url, timeout=0.3, names={1: "spin", 2: "orbit"}) as link:
        with pytest.raises(DriveExceptionResponse) as info:
            await link.read(2, 105, 2)  # 106 is not in the map
        err = info.value
        assert (err.exception_code, err.register, err.count) == (2, 105, 2)
        assert str(err).startswith("orbit drive (id 2), registers 105..106 (AT_SETPOINT_BAND .. ?): request FC03")
        with pytest.raises(DriveExceptionResponse) as info:
            await link.read(2, 6, 2)
        assert "orbit drive (id 2), registers 6..7 (FAULT .. ?): request FC03 refused" in str(info.value)
        assert "FAULT (6)" not in str(info.value)
        with pytest.raises(DriveExceptionResponse) as info:
            await link.write(1, 104, [10, 10, 0])  # FC16 over 104..106
        assert info.value.exception_code == 2
        assert "spin drive (id 1), registers 104..106 (COMM_LOSS_TIMEOUT .. ?): request FC16" in str(info.value)
        with pytest.raises(DriveExceptionResponse) as info:
            await link.write(1, 106, [0])  # FC06: one register, named as before
        assert info.value.exception_code == 2 and info.value.count == 1
        assert "spin drive (id 1), register unknown register (106): request FC06" in str(info.value)
        assert await link.read(1, 100, 6) == [3000, 2500, 50, 50, 10, 5]  # nothing written


async def test_run_at_max_speed_settles_with_a_zero_band(sim):
    """2500 rpm = 16666.7 counts: the REF sent is 16666 (2499.9 rpm), never 16667 (2500.05 rpm,
    clamped by the drive, so never at setpoint with AT_SETPOINT_BAND 0)."""
    for dev in (1, 2):
        sim.models[dev].write(sim_registers.AT_SETPOINT_BAND, [0])
    async with rig(sim, DriveLimits(math.inf, math.inf)) as r:
        assert r.spin.reference_for(2500 * RPM) == 16666 and r.orbit.reference_for(-2500 * RPM) == -16666
        assert r.spin.reference_for(1500 * RPM) == 10000 and r.spin.reference_for(2499.96 * RPM) == 16666
        await r.set_speeds(2500 * RPM, -2500 * RPM)
        st = await r.wait_settled(hold=0.05, timeout=5)
        assert st.spin.at_setpoint and st.orbit.at_setpoint
        for dev, ref in ((1, 16666), (2, -16666)):
            regs = sim.regs(dev)
            assert regs["REF"] == ref and regs["ACT"] == ref and not regs["SW"] & 0x400  # no ABOVE_LIMIT
        await r.stop()
    assert sim.regs(1)["ACT"] == sim.regs(2)["ACT"] == 0


async def test_wait_settled_timeout_names_the_drives(sim):
    async with rig(sim) as r:
        await r.set_speeds(2400 * RPM, 0.0)
        with pytest.raises(DriveError, match=r"not at setpoint.*spin \(id 1\)"):
            await r.wait_settled(hold=0.05, timeout=0.05)


async def test_warns_when_one_lost_request_would_trip_the_watchdog(tcp_sim, caplog):
    async with rig(tcp_sim, timeout=1.0, comm_loss_timeout=1.0):
        pass
    assert "a single lost request trips them" in caplog.text
    caplog.clear()
    async with rig(tcp_sim, timeout=0.3, comm_loss_timeout=1.0):
        pass
    assert "single lost request" not in caplog.text


async def test_entry_writes_only_parameters_the_drives_do_not_hold(sim):
    """The configured watchdog reaches a drive that was power-cycled to its default (1.0 s);
    a client entering while the drives run with the values held writes nothing (a write
    would be refused with exception 03 while running)."""
    assert sim.models[1].parameter(PARAM["COMM_LOSS_TIMEOUT"]) == 10  # the drive's default
    async with rig(sim, comm_loss_timeout=0.7) as r:
        assert sim.models[1].parameter(PARAM["COMM_LOSS_TIMEOUT"]) == 7
        assert sim.models[2].parameter(PARAM["COMM_LOSS_TIMEOUT"]) == 7
        await r.set_speeds(300 * RPM, 0.0)
        await r.wait_settled(hold=0.1, timeout=5)
        assert (
            params_to_write(r.spin.params, r._params) == params_to_write(r.orbit.params, r._params) == {}
        )  # held: nothing to write
        r._params["comm_loss_timeout"] = 0.9
        assert params_to_write(r.spin.params, r._params) == {"comm_loss_timeout": 0.9}
        with pytest.raises(DriveExceptionResponse):  # what that write meets while running
            await r.spin.configure(comm_loss_timeout=0.9)


async def test_a_new_orbit_speed_on_running_drives_writes_the_orbit_ref_alone(sim):
    """Block to block only the orbit speed changes: set_speeds reads both statuses (the trip
    check) and writes the orbit drive's REF, nothing else; the same speeds again write nothing."""
    writes: list[tuple[int, int, list[int]]] = []
    for dev, model in sim.models.items():
        real = model.write

        def spy(address, values, _dev=dev, _real=real):
            writes.append((_dev, address, list(values)))
            return _real(address, values)

        model.write = spy
    async with rig(sim) as r:
        await r.set_speeds(1000 * RPM, 600 * RPM)
        await r.wait_settled(hold=0.05, timeout=5)
        writes.clear()
        await r.set_speeds(1000 * RPM, -450 * RPM)
        assert writes == [(2, sim_registers.REF, [(-3000) & 0xFFFF])]
        await r.wait_settled(hold=0.05, timeout=5)
        assert sim.rpm(2) == pytest.approx(-450, abs=5) and sim.rpm(1) == pytest.approx(1000, abs=5)
        writes.clear()
        await r.set_speeds(1000 * RPM, -450 * RPM)
        assert writes == []
        await r.stop()
    assert sim.regs(1)["ACT"] == sim.regs(2)["ACT"] == 0
