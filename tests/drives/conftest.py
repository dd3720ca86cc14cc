from __future__ import annotations

import asyncio
import logging
import threading

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


@pytest.fixture
def threaded_sim():
    """The drives (slow ramps: about 0.8 s wall from 1500 rpm) served from a loop in another
    thread, so that the command's own `asyncio.run` and signal handlers own this one."""
    loop = asyncio.new_event_loop()
    thread = threading.Thread(target=loop.run_forever, daemon=True)
    thread.start()
    models = make_models(speedup=3.0)
    endpoint = asyncio.run_coroutine_threadsafe(serve("tcp", models), loop).result(10)
    try:
        yield SimDrives("tcp", models, endpoint, loop)
    finally:
        asyncio.run_coroutine_threadsafe(endpoint.aclose(), loop).result(10)
        loop.call_soon_threadsafe(loop.stop)
        thread.join(10)
