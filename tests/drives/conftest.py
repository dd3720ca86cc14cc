from __future__ import annotations

import logging

import pytest
from pathlib import Path

from support.drives_testkit import SPEEDUP, SimDrives, make_models, serve, served_from_a_thread
from support.rig_configs import modbus_only_lab

from orbitrig.config.home import HOME_ENV


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


@pytest.fixture(scope="session")
def _modbus_only_lab(tmp_path_factory) -> Path:
    return modbus_only_lab(tmp_path_factory.mktemp("modbus-only-lab"))


@pytest.fixture(autouse=True)
def _no_can_node(_modbus_only_lab, monkeypatch):
    """The drives here are the simulator's alone (a Modbus server, no CAN bus): the lab's rig has
    no CAN sensor node, so `orbitrig drives run` watches none (tests/drives/test_drives_run_supply.py
    gives it one)."""
    monkeypatch.setenv(HOME_ENV, str(_modbus_only_lab))


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
    """The drives (slow ramps: about 0.8 s wall from 1500 rpm) over TCP, served from another thread."""
    with served_from_a_thread("tcp", 3.0) as sim:
        yield sim


@pytest.fixture(params=["tcp", "rtu"])
def threaded_drives(request):
    """As `sim` (TCP or RTU, fast ramps), served from another thread: for the command run in-process."""
    with served_from_a_thread(request.param, SPEEDUP) as sim:
        yield sim


@pytest.fixture(params=["tcp", "rtu"])
def threaded_slow_drives(request):
    """As `slow_drives` (TCP or RTU, about 0.8 s wall from 1500 rpm), served from another thread."""
    with served_from_a_thread(request.param, 3.0) as sim:
        yield sim


@pytest.fixture
def threaded_tcp_sim():
    """As `tcp_sim` (fast ramps), served from another thread."""
    with served_from_a_thread("tcp", SPEEDUP) as sim:
        yield sim
