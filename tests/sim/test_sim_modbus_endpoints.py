"""SimRig serves both drives (ids 1, 2) over Modbus TCP and RTU-over-pty; read here
by independent clients (mbpoll, and raw frames written from the protocol)."""

from __future__ import annotations

import asyncio
import math
import os
import re
import shutil
import struct
import tty

import pytest

from sim.config import SimConfig
from sim.rig import SimRig


def crc_modbus(data: bytes) -> int:
    crc = 0xFFFF
    for b in data:
        crc ^= b
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return crc


async def rtu_read(path: str, unit: int, address: int, count: int) -> list[int]:
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    tty.setraw(fd)
    try:
        req = struct.pack(">BBHH", unit, 3, address, count)
        os.write(fd, req + struct.pack("<H", crc_modbus(req)))
        want = 5 + 2 * count
        buf = b""
        for _ in range(300):
            try:
                buf += os.read(fd, 256)
            except BlockingIOError:
                await asyncio.sleep(0.01)
            if len(buf) >= want:
                break
        assert len(buf) == want, buf
        assert struct.unpack("<H", buf[-2:])[0] == crc_modbus(buf[:-2])
        assert buf[:3] == bytes([unit, 3, 2 * count])
        return list(struct.unpack(f">{count}H", buf[3:-2]))
    finally:
        os.close(fd)


async def test_both_drives_on_tcp_and_rtu():
    async with SimRig(SimConfig(), modbus_rtu_pty=True, can_channel=None) as rig:
        assert rig.modbus_url.startswith("tcp://127.0.0.1:")
        assert rig.modbus_rtu_path and os.path.exists(rig.modbus_rtu_path)
        # SPEED_SCALE (address 100) of both drives over RTU; stopped drives read ACT = 0
        assert await rtu_read(rig.modbus_rtu_path, 1, 100, 1) == [3000]
        assert await rtu_read(rig.modbus_rtu_path, 2, 4, 1) == [0]
        rig.local_control(spin=100.0, orbit=-50.0)
        await asyncio.sleep(0.05)
        act = (await rtu_read(rig.modbus_rtu_path, 2, 4, 1))[0]
        rpm = (act - 65536 if act >= 32768 else act) * 3000 / 20000
        assert abs(rpm - (-50.0 * 60 / (2 * 3.141592653589793))) <= 0.3  # one register step
        # mbpoll: an independent Modbus client (installed by .ci/run)
        assert shutil.which("mbpoll"), "mbpoll is needed (apt-get install mbpoll)"
        port = rig.modbus_url.rsplit(":", 1)[1]
        proc = await asyncio.create_subprocess_exec(
            "mbpoll",
            "-m",
            "tcp",
            "-p",
            port,
            "-a",
            "2",
            "-r",
            "101",
            "-c",
            "2",
            "-t",
            "4",
            "-1",
            "127.0.0.1",
            stdout=asyncio.subprocess.PIPE,
            stderr=asyncio.subprocess.PIPE,
        )
        out, err = await asyncio.wait_for(proc.communicate(), 10)
        assert proc.returncode == 0, err
        # reference numbers are address + 1: SPEED_SCALE (100), MAX_SPEED (101)
        assert dict(re.findall(r"\[(\d+)\]:\s+(-?\d+)", out.decode())) == {"101": "3000", "102": "2500"}


async def test_the_reported_speeds_are_the_drives_now_not_the_last_board_tick():
    """A busy host runs the board's tick late; the speeds the simulator reports (its control API's
    `state`) must still be what a read of ACT finds now, so a test at a standstill prompt sees one."""
    async with SimRig(SimConfig(), tick=30.0, adc_pty=False, can_channel=None) as rig:
        await asyncio.sleep(0.05)  # the board's first tick has run; the next is 30 s away
        rig.local_control(spin=100.0, orbit=-50.0)
        await asyncio.sleep(0.3)
        spin, orbit = rig.speeds
        drives = rig.drives
        assert spin == pytest.approx(drives[1].actual_rpm * 2 * math.pi / 60, abs=0.5)
        assert orbit == pytest.approx(drives[2].actual_rpm * 2 * math.pi / 60, abs=0.5)
        assert spin > 5.0 and orbit < -5.0  # ramping: not the 0 of the last tick
        assert rig.state()["spin"] == pytest.approx(spin, abs=0.5)
