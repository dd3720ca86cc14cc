"""The emulated drives over real Modbus: an independent pymodbus client (TCP and
RTU over the pty) and mbpoll, held to docs/protocols/drive-modbus.md."""

from __future__ import annotations

import asyncio
import contextlib
import os
import re
import shutil
import socket
import subprocess
import time
import tty

import pytest
from pymodbus.client import AsyncModbusSerialClient, AsyncModbusTcpClient
from pymodbus.exceptions import ModbusIOException
from support.sim_drive_helpers import (
    ABOVE_LIMIT,
    ACT,
    AT_SETPOINT,
    COAST,
    COMM_LOSS_TIMEOUT,
    CW,
    DECEL_TIME,
    EMERGENCY,
    FAULT,
    MAX_SPEED,
    OFF_2_STA,
    OFF_3_STA,
    RAMP_STOP,
    RDY_ON,
    RDY_REF,
    RDY_RUN,
    READY,
    REF,
    REF2,
    REMOTE,
    RESET,
    RUN,
    SW,
    TORQUE,
    TRIPPED,
    ref_counts,
    s16,
    u16,
)

from sim.modbus_server import serve_modbus_rtu_pty

RATE = 600.0  # rpm/s: default ACCEL/DECEL_TIME 5 s per SPEED_SCALE 3000 rpm
COUNT_RPM = 3000 / 20000  # rpm per REF / ACT count (default SPEED_SCALE)
TOL = 0.2  # rpm: ACT quantisation


async def rd(c, address, count=1, dev=2):
    r = await c.read_holding_registers(address, count=count, device_id=dev)
    assert not r.isError(), r
    return r.registers


async def wr(c, address, value, dev=2):
    if isinstance(value, list):
        r = await c.write_registers(address, value, device_id=dev)
    else:
        r = await c.write_register(address, value, device_id=dev)
    assert not r.isError(), r
    return r


async def exception_code(request):
    r = await request
    assert r.isError(), r
    return r.exception_code


async def start(c, rpm, dev=2):
    await wr(c, REF, ref_counts(rpm), dev)
    await wr(c, CW, READY, dev)
    await wr(c, CW, RUN, dev)


async def wait_status(c, bit, dev=2, *, timeout=3.0, present=True):
    deadline = time.monotonic() + timeout
    while True:
        sw = (await rd(c, SW, 1, dev))[0]
        if bool(sw & bit) == present:
            return sw
        assert time.monotonic() < deadline, f"status bit {bit:#x} never {present}: {sw:#06x}"
        await asyncio.sleep(0.01)


async def act_rpm(c, dev=2):
    return s16((await rd(c, ACT, 1, dev))[0]) * COUNT_RPM


# ----------------------------------------------------------------- TCP
async def test_start_sequence_status_word(client, tcp):
    assert tcp.url == f"tcp://127.0.0.1:{tcp.port}"
    sw = (await rd(client, SW))[0]
    assert not sw & (RDY_ON | RDY_RUN | RDY_REF | REMOTE)
    await wr(client, CW, READY)
    sw = (await rd(client, SW))[0]
    assert sw & (RDY_ON | OFF_2_STA | OFF_3_STA | REMOTE) == RDY_ON | OFF_2_STA | OFF_3_STA | REMOTE
    assert not sw & (RDY_RUN | RDY_REF | TRIPPED)
    await wr(client, CW, [RUN, ref_counts(300)])  # FC 16: CW and REF together
    sw = (await rd(client, SW))[0]
    assert sw & (RDY_ON | RDY_RUN | RDY_REF) == RDY_ON | RDY_RUN | RDY_REF
    assert await rd(client, CW, 3) == [RUN, ref_counts(300), 0]
    # the other drive is untouched
    assert not (await rd(client, SW, 1, dev=1))[0] & RDY_ON


async def test_ramp_to_setpoint_along_accel_time(client, clock):
    await wr(client, REF, ref_counts(1500))
    await wr(client, CW, READY)
    t_run_0 = clock()
    await wr(client, CW, RUN)
    t_run_1 = clock()
    samples = 0
    while True:
        tb = clock()
        sw, act = await rd(client, SW, 2)
        ta = clock()
        rpm = s16(act) * COUNT_RPM
        lo = min(1500.0, RATE * (tb - t_run_1))
        hi = min(1500.0, RATE * (ta - t_run_0))
        assert lo - TOL <= rpm <= hi + TOL, (lo, rpm, hi)
        samples += 1
        if sw & AT_SETPOINT:
            break
        assert sw & RDY_REF and s16((await rd(client, TORQUE))[0]) > 0  # accelerating
        await asyncio.sleep(0.01)
    assert samples >= 5
    assert rpm >= 1500 - 5 - TOL  # AT_SETPOINT_BAND = 5 rpm
    await asyncio.sleep(0.05)
    assert await act_rpm(client) == pytest.approx(1500, abs=TOL)


async def test_orbit_negative_reference_is_backward_whirl(client):
    await start(client, -900)
    assert await act_rpm(client) <= 0.0
    sw = await wait_status(client, AT_SETPOINT)  # within the 5 rpm band
    assert not sw & ABOVE_LIMIT
    assert await act_rpm(client) == pytest.approx(-900, abs=5 + TOL)
    await asyncio.sleep(0.05)
    assert await act_rpm(client) == pytest.approx(-900, abs=TOL)
    assert s16((await rd(client, REF))[0]) == -6000


async def test_spin_drive_negative_reference_stays_at_standstill(client):
    await start(client, -900, dev=1)
    await asyncio.sleep(0.2)
    sw = (await rd(client, SW, 1, dev=1))[0]
    assert sw & RDY_REF and sw & ABOVE_LIMIT
    assert await act_rpm(client, dev=1) == 0.0


async def wait_act(c, rpm, dev=2, *, timeout=3.0):
    deadline = time.monotonic() + timeout
    while abs(await act_rpm(c, dev) - rpm) > TOL:
        assert time.monotonic() < deadline, f"ACT never {rpm} rpm: {await act_rpm(c, dev)}"
        await asyncio.sleep(0.01)


async def test_clamp_at_max_speed_sets_above_limit(client):
    await wr(client, MAX_SPEED, 1000)
    await start(client, 1800)
    await wait_act(client, 1000)
    sw = (await rd(client, SW))[0]
    assert sw & ABOVE_LIMIT and sw & RDY_REF and not sw & AT_SETPOINT  # REF 1800 rpm is not reached
    assert (await rd(client, REF))[0] == ref_counts(1800)  # REF reads back as written
    await wr(client, REF, ref_counts(900))
    assert not (await rd(client, SW))[0] & ABOVE_LIMIT
    assert (await wait_status(client, AT_SETPOINT)) & ABOVE_LIMIT == 0


async def test_at_setpoint_is_not_set_while_the_reference_is_clamped(client):
    """REF = 20000 (3000 rpm) on id 2, MAX_SPEED 2500 rpm: the drive runs at ACT = 16667 with
    ABOVE_LIMIT, and |ACT - REF| = 500 rpm > AT_SETPOINT_BAND (5 rpm): no AT_SETPOINT."""
    assert await rd(client, 100, 6) == [3000, 2500, 50, 50, 10, 5]
    await start(client, 3000)
    await wait_act(client, 2500)
    await asyncio.sleep(0.05)
    regs = await rd(client, CW, 7)
    assert regs[REF] == 20000 and regs[ACT] == 16667
    assert regs[SW] == 0x0637  # RDY_ON, RDY_RUN, RDY_REF, OFF_2_STA, OFF_3_STA, REMOTE, ABOVE_LIMIT
    # REF 2500 rpm is 16667 counts = 2500.05 rpm: still clamped, but within the band of ACT
    await wr(client, REF, 16667)
    await asyncio.sleep(0.05)
    assert (await rd(client, SW))[0] == 0x0637 | AT_SETPOINT


async def test_parameter_write_while_running_is_03_and_changes_nothing(client):
    before = await rd(client, 100, 6)
    await start(client, 600)
    assert await exception_code(client.write_register(102, 20, device_id=2)) == 3
    assert await exception_code(client.write_registers(100, [1000, 900], device_id=2)) == 3
    assert await rd(client, 100, 6) == before
    # out of range while stopped is 03 as well; a valid value is taken
    assert await exception_code(client.write_register(102, 0, device_id=1)) == 3
    await wr(client, 102, 20, dev=1)
    assert (await rd(client, 102, 1, dev=1))[0] == 20


async def test_unknown_and_read_only_addresses_are_02(client):
    for address, count in [(7, 1), (5, 3), (99, 1), (106, 1), (500, 2)]:
        assert await exception_code(client.read_holding_registers(address, count=count, device_id=2)) == 2
    for address in (SW, ACT, TORQUE, FAULT, 7, 200):
        assert await exception_code(client.write_register(address, 1, device_id=2)) == 2
    assert await exception_code(client.write_registers(1, [1, 2, 3], device_id=2)) == 2
    assert await rd(client, REF, 2) == [0, 0]  # nothing of the failed write applied
    # only function codes 03, 06 and 16 are served
    assert await exception_code(client.read_input_registers(0, count=1, device_id=2)) == 1
    assert await exception_code(client.read_coils(0, count=1, device_id=2)) == 1


async def test_ref2_reads_back(client):
    await wr(client, REF2, u16(-321))
    assert s16((await rd(client, REF2))[0]) == -321


async def stop_time(client, clock, cw):
    """Simulated time from writing `cw` at 1500 rpm until ACT = 0 (bounds)."""
    await start(client, 1500)
    await wait_status(client, AT_SETPOINT)
    await asyncio.sleep(0.05)  # at 1500 rpm exactly, not just inside the band
    t0 = clock()
    await wr(client, CW, cw)
    t1 = clock()
    while True:
        tb = clock()
        act = (await rd(client, ACT))[0]
        ta = clock()
        if act == 0:
            return t0, t1, tb, ta
        await asyncio.sleep(0.002)


async def test_off1_ramp_stop_takes_decel_time(client, clock):
    t0, t1, tb, ta = await stop_time(client, clock, RAMP_STOP)
    assert ta - t0 >= 1500 / RATE - 0.01  # not faster than DECEL_TIME
    assert tb - t1 <= 1500 / RATE + 0.3  # and not much slower (polling)
    sw = (await rd(client, SW))[0]
    assert sw & RDY_ON and not sw & (RDY_RUN | RDY_REF)


async def test_off3_emergency_stop_ten_times_faster(client, clock):
    t0, t1, tb, ta = await stop_time(client, clock, EMERGENCY)
    assert ta - t0 >= 1500 / RATE / 10 - 0.01
    assert tb - t1 <= 1500 / RATE / 10 + 0.3
    sw = (await rd(client, SW))[0]
    assert not sw & RDY_ON  # switch-on inhibited until 0x0476
    await wr(client, CW, READY)
    assert (await rd(client, SW))[0] & (RDY_ON | OFF_3_STA) == RDY_ON | OFF_3_STA


async def test_off3_status_bit_while_stopping(client):
    await start(client, 1500)
    await wait_status(client, AT_SETPOINT)
    await wr(client, DECEL_TIME, 500, dev=1)  # other drive: unaffected
    await wr(client, CW, EMERGENCY)
    sw, _, torque = await rd(client, SW, 3)
    assert not sw & OFF_3_STA and sw & OFF_2_STA
    assert s16(torque) < -10000  # braking hard: more than 100 % torque


async def test_off2_coast_stop_torque_off_at_once(client, clock):
    await start(client, 1500)
    await wait_status(client, AT_SETPOINT)
    await asyncio.sleep(0.05)  # at 1500 rpm exactly, not just inside the band
    t0 = clock()
    await wr(client, CW, COAST)
    t0_after = clock()
    sw, act, torque = await rd(client, SW, 3)
    assert not sw & OFF_2_STA and not sw & (RDY_ON | RDY_RUN | RDY_REF)
    assert torque == 0
    await asyncio.sleep(0.1)
    t1 = clock()
    rpm = await act_rpm(client)
    t2 = clock()
    # coasting at the friction deceleration (150 rpm/s), far slower than DECEL_TIME
    assert 1500 - 150 * (t2 - t0) - TOL <= rpm <= 1500 - 150 * (t1 - t0_after) + TOL
    assert rpm > 1500 - RATE * (t1 - t0_after)


async def test_trip_coast_stop_and_reset_only_when_cause_gone(client, drives):
    await start(client, 1500)
    await wait_status(client, AT_SETPOINT)
    drives[2].inject_fault(2310)
    sw, act, torque, fault = await rd(client, SW, 4)
    assert sw & TRIPPED and fault == 2310 and torque == 0
    assert not sw & (RDY_ON | RDY_RUN | RDY_REF)
    await asyncio.sleep(0.05)
    assert 0 < await act_rpm(client) < 1500  # coasting down
    await wr(client, CW, RUN)  # RUN ignored while tripped
    assert (await rd(client, SW))[0] & TRIPPED
    await wr(client, CW, RESET)  # edge, but the cause is still there
    await wr(client, CW, READY)
    assert (await rd(client, FAULT))[0] == 2310
    drives[2].clear_fault_cause()
    await wr(client, CW, RESET)
    await wr(client, CW, READY)
    sw, _, _, fault = await rd(client, SW, 4)
    assert not sw & TRIPPED and fault == 0 and sw & RDY_ON
    await wr(client, CW, RUN)
    await wait_status(client, AT_SETPOINT)


async def test_comm_loss_watchdog_and_other_device_id(client, clock):
    for dev in (1, 2):
        await wr(client, COMM_LOSS_TIMEOUT, 3, dev)  # 0.3 s wall
        await wr(client, DECEL_TIME, 300, dev)  # 100 rpm/s: a ramp, distinct from coasting
        await start(client, 1500, dev)
    deadline = time.monotonic() + 6.0
    while True:  # both drives read in turn: each hears from us well within its 0.3 s watchdog
        sws = [(await rd(client, SW, 1, dev))[0] for dev in (1, 2)]
        if all(sw & AT_SETPOINT for sw in sws):
            break
        assert time.monotonic() < deadline, f"not both at setpoint: {[f'{sw:#06x}' for sw in sws]}"
        await asyncio.sleep(0.01)
    t_last_0 = clock()
    await rd(client, SW, 1, dev=2)  # the last request drive 2 sees for a while
    t_last_1 = clock()
    deadline = time.monotonic() + 0.6
    while time.monotonic() < deadline:  # keep talking to drive 1 only
        assert not (await rd(client, SW, 1, dev=1))[0] & TRIPPED
        await asyncio.sleep(0.03)
    tb = clock()
    sw, act, torque, fault = await rd(client, SW, 4, dev=2)
    ta = clock()
    assert sw & TRIPPED and fault == 7510
    assert s16(torque) < 0  # powered ramp stop, not a coast
    expiry = (t_last_0 + 0.3 * 10, t_last_1 + 0.3 * 10)  # 0.3 s wall at speed-up 10
    rpm = s16(act) * COUNT_RPM
    assert 1500 - 100 * (ta - expiry[0]) - TOL <= rpm <= 1500 - 100 * (tb - expiry[1]) + TOL
    sw1 = (await rd(client, SW, 1, dev=1))[0]
    assert not sw1 & TRIPPED and sw1 & AT_SETPOINT
    await wr(client, CW, RESET)  # the link is back: reset clears 7510
    assert not (await rd(client, SW))[0] & TRIPPED


async def test_unknown_device_id_gets_gateway_exception(client):
    assert await exception_code(client.read_holding_registers(0, count=1, device_id=7)) == 0x0B


async def test_set_unresponsive_makes_requests_time_out(tcp, drives):
    c = AsyncModbusTcpClient("127.0.0.1", port=tcp.port, timeout=0.3, retries=0)
    assert await c.connect()
    try:
        await wr(c, COMM_LOSS_TIMEOUT, 2)  # 0.2 s
        await wr(c, CW, READY)
        tcp.set_unresponsive(True)
        t0 = time.monotonic()
        with pytest.raises(ModbusIOException):
            await c.read_holding_registers(SW, count=1, device_id=2)
        assert time.monotonic() - t0 >= 0.25
        tcp.set_unresponsive(False)
        sw, _, _, fault = await rd(c, SW, 4)
        # a dead link: the drive heard nothing either, so its watchdog ran down
        assert sw & TRIPPED and fault == 7510
    finally:
        c.close()


async def test_aclose_releases_port_and_is_idempotent(drives):
    from sim.modbus_server import serve_modbus_tcp

    endpoint = await serve_modbus_tcp(drives)
    port = endpoint.port
    await endpoint.aclose()
    await endpoint.aclose()
    with pytest.raises(OSError):
        socket.create_connection(("127.0.0.1", port), timeout=0.5).close()
    again = await serve_modbus_tcp(drives, port=port)
    assert again.port == port
    await again.aclose()


# ------------------------------------------------------------ RTU / pty
@pytest.fixture
async def rtu(drives):
    endpoint = await serve_modbus_rtu_pty(drives, baud=19200)
    yield endpoint
    await endpoint.aclose()


async def test_rtu_over_pty(rtu):
    assert rtu.url == f"rtu://{rtu.path}?baud=19200" and rtu.port is None
    for _ in range(2):  # the path can be opened again after a client closed it
        c = AsyncModbusSerialClient(rtu.path, baudrate=19200, timeout=0.5, retries=0)
        assert await c.connect()
        try:
            for dev in (1, 2):
                await wr(c, CW, READY, dev)
                await wr(c, CW, [RUN, ref_counts(300)], dev)
                sw = (await rd(c, SW, 1, dev))[0]
                assert sw & (RDY_ON | RDY_RUN | RDY_REF | REMOTE) == RDY_ON | RDY_RUN | RDY_REF | REMOTE
            assert await exception_code(c.read_holding_registers(7, count=1, device_id=1)) == 2
            with pytest.raises(ModbusIOException):  # no such drive on the line: silence
                await c.read_holding_registers(0, count=1, device_id=3)
            assert (await rd(c, REF, 1, 2))[0] == ref_counts(300)  # line still in step
            await wr(c, CW, READY, 1)
            await wr(c, CW, READY, 2)
        finally:
            c.close()


async def test_rtu_set_unresponsive(rtu):
    c = AsyncModbusSerialClient(rtu.path, baudrate=19200, timeout=0.3, retries=0)
    assert await c.connect()
    try:
        rtu.set_unresponsive(True)
        with pytest.raises(ModbusIOException):
            await c.read_holding_registers(SW, count=1, device_id=1)
        rtu.set_unresponsive(False)
        await rd(c, SW, 1, 1)
    finally:
        c.close()


# --------------------------------------------------------------- mbpoll
MBPOLL = shutil.which("mbpoll")  # the independent client: .ci/run installs it (apt-get install mbpoll)


async def mbpoll(*args):
    """Run mbpoll (reference numbers = address + 1) off the event loop."""
    assert MBPOLL, "mbpoll is not installed: apt-get install mbpoll (the README's test prerequisites)"
    proc = await asyncio.to_thread(
        subprocess.run, [MBPOLL, "-1", "-o", "1", *args], capture_output=True, text=True, timeout=20
    )
    return proc


def mbpoll_values(stdout):
    return {int(k): int(v) for k, v in re.findall(r"^\[(\d+)\]:\s+(\d+)", stdout, re.M)}


async def test_mbpoll_tcp_read_and_write(tcp, clock):
    net = ["-m", "tcp", "-p", str(tcp.port)]
    p = await mbpoll(*net, "-a", "2", "-r", "2", "127.0.0.1", str(u16(-6000)))  # REF = -900 rpm
    assert p.returncode == 0, p.stdout + p.stderr
    p = await mbpoll(*net, "-a", "2", "-r", "1", "127.0.0.1", str(READY))
    assert p.returncode == 0, p.stdout + p.stderr
    p = await mbpoll(*net, "-a", "2", "-r", "1", "127.0.0.1", str(RUN))
    assert p.returncode == 0, p.stdout + p.stderr
    await asyncio.sleep(0.4)  # 4 s simulated: at setpoint (and inside the 1 s watchdog)
    p = await mbpoll(*net, "-a", "2", "-r", "1", "-c", "7", "127.0.0.1")
    assert p.returncode == 0, p.stdout + p.stderr
    regs = mbpoll_values(p.stdout)
    assert regs[1] == RUN and s16(regs[2]) == -6000
    assert regs[4] & (RDY_REF | AT_SETPOINT | REMOTE) == RDY_REF | AT_SETPOINT | REMOTE
    assert s16(regs[5]) == -6000 and regs[7] == 0
    p = await mbpoll(*net, "-a", "2", "-r", "101", "-c", "6", "127.0.0.1")
    assert mbpoll_values(p.stdout) == {101: 3000, 102: 2500, 103: 50, 104: 50, 105: 10, 106: 5}
    p = await mbpoll(*net, "-a", "2", "-r", "8", "127.0.0.1")  # address 7: not in the map
    assert p.returncode != 0 and "illegal data address" in (p.stdout + p.stderr).lower()


async def test_mbpoll_rtu_read_and_write(rtu, drives):
    line = ["-m", "rtu", "-b", "19200", "-P", "none"]
    p = await mbpoll(*line, "-a", "1", "-r", "2", rtu.path, "4000")
    assert p.returncode == 0, p.stdout + p.stderr
    p = await mbpoll(*line, "-a", "1", "-r", "1", "-c", "7", rtu.path)
    assert p.returncode == 0, p.stdout + p.stderr
    regs = mbpoll_values(p.stdout)
    assert regs[2] == 4000 and regs[7] == 0
    assert drives[1].read(REF, 1) == [4000] and drives[2].read(REF, 1) == [0]


def _rtu(dev, pdu):
    """An RTU frame built here (independent of sim's framing): id, PDU, CRC-16 low byte first."""
    body = bytes([dev]) + pdu
    crc = 0xFFFF
    for b in body:
        crc ^= b
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return body + crc.to_bytes(2, "little")


async def _read_exactly(fd, n, timeout=2.0):
    got, deadline = b"", time.monotonic() + timeout
    while len(got) < n and time.monotonic() < deadline:
        try:
            got += os.read(fd, 1024)
        except BlockingIOError:
            await asyncio.sleep(0.005)
    return got


async def test_rtu_back_to_back_requests_each_answered_once_in_order(rtu, drives):
    fd = os.open(rtu.path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    tty.setraw(fd)
    try:
        w = _rtu(2, bytes([6, 0, REF2, 0x12, 0x34]))  # FC06 REF2 = 0x1234 on the orbit drive
        r1 = _rtu(1, bytes([3, 0, 0, 0, 7]))
        r2 = _rtu(2, bytes([3, 0, REF2, 0, 1]))
        bad = _rtu(2, bytes([3, 0, 7, 0, 1]))  # address 7: exception 02
        os.write(fd, w + r1 + r2)  # three frames in one write
        os.write(fd, b"\x55" + bad)  # a noise byte, then a frame
        os.write(fd, r2)
        want = [
            w,
            _rtu(1, bytes([3, 14]) + bytes(b for v in drives[1].read(0, 7) for b in v.to_bytes(2, "big"))),
            _rtu(2, bytes([3, 2, 0x12, 0x34])),
            _rtu(2, bytes([0x83, 2])),
            _rtu(2, bytes([3, 2, 0x12, 0x34])),
        ]
        got = await _read_exactly(fd, sum(map(len, want)))
        await asyncio.sleep(0.05)
        with contextlib.suppress(BlockingIOError):
            got += os.read(fd, 1024)  # nothing more: no request answered twice
        assert got.hex(" ") == b"".join(want).hex(" ")
        assert rtu._server.requests == 5 and rtu._server.answered == 5
    finally:
        os.close(fd)
