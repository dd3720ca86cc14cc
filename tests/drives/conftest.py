from __future__ import annotations

import logging

import pytest
from support.drives_testkit import SimDrives, make_models, serve


@pytest.fixture(params=["tcp", "rtu"])
async def sim(request) -> SimDrives:
    """The simulator's two drives behind a real Modbus server, TCP or RTU on a pty."""
    models = make_models()
    endpoint = await serve(request.param, models)
    try:
        yield SimDrives(request.param, models, endpoint)
    finally:
        await endpoint.aclose()


@pytest.fixture
async def tcp_sim() -> SimDrives:
    models = make_models()
    endpoint = await serve("tcp", models)
    try:
        yield SimDrives("tcp", models, endpoint)
    finally:
        await endpoint.aclose()


@pytest.fixture(autouse=True)
def _quiet_pymodbus():
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
    yield


@pytest.fixture(params=["tcp", "rtu"])
async def slow_drives(request) -> SimDrives:
    """The drives with slow ramps (about 0.8 s wall from 1500 rpm to zero), TCP or RTU: a
    command that exits before standstill is caught with the drives still turning."""
    models = make_models(speedup=3.0)
    endpoint = await serve(request.param, models)
    try:
        yield SimDrives(request.param, models, endpoint)
    finally:
        await endpoint.aclose()
