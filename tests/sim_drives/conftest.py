"""Fixtures of the drive-emulation tests: both drives behind a live Modbus server."""

from __future__ import annotations

import pytest
from pymodbus.client import AsyncModbusTcpClient
from support.sim_drive_helpers import SpeedupClock

from sim.drive_model import DriveModel
from sim.modbus_server import serve_modbus_tcp

SPEEDUP = 10.0  # simulated seconds per wall second in the server tests


@pytest.fixture
def clock():
    return SpeedupClock(SPEEDUP)


@pytest.fixture
def drives(clock):
    return {
        1: DriveModel(1, clock=clock, bidirectional=False),  # spin: one direction
        2: DriveModel(2, clock=clock, bidirectional=True),  # orbit: signed
    }


@pytest.fixture
async def tcp(drives):
    endpoint = await serve_modbus_tcp(drives)
    yield endpoint
    await endpoint.aclose()


@pytest.fixture
async def client(tcp):
    c = AsyncModbusTcpClient("127.0.0.1", port=tcp.port, timeout=1.0, retries=0)
    assert await c.connect()
    yield c
    c.close()
