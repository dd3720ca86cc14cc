"""An abort that no run carries out, on an RTU rig whose serial port a run still holds.

The service's own emergency stop (orbitrig.service.idle_stop) opens the drives' port; a serial
port is opened exclusively, so while a run that is being opened (and is now cancelled by the
abort) still holds it, the first try fails. The stop then waits for that run to let go of the
port and sends OFF3 to both drives; only a run that keeps the port past the bound leaves the
abort answered "NOT sent". Real parts: the simulator's drives behind its Modbus RTU server on a
pty, the link orbitrig's own (drives.link over drives.rtu)."""

from __future__ import annotations

import asyncio

import pytest
from support.drives_testkit import CW_EMERGENCY, SimDrives, make_models, serve

from drives.link import ModbusLink
from orbitrig.config import Drives
from orbitrig.service import idle_stop

pytestmark = pytest.mark.timeout(60)


async def _rtu_rig() -> SimDrives:
    models = make_models()
    return SimDrives("rtu", models, await serve("rtu", models))


async def _holder(link: ModbusLink, hold_s: float) -> None:
    """A run that holds the drives' port while it is being opened, and lets go after `hold_s`."""
    try:
        await asyncio.sleep(hold_s)
    finally:
        await link.close()


async def test_the_stop_waits_for_the_run_that_holds_the_port_and_gets_through():
    sim = await _rtu_rig()
    run_link = ModbusLink(sim.url, timeout=0.15)
    try:
        await run_link.connect()  # the run opening the rig holds the serial port (exclusive)
        holder = asyncio.create_task(_holder(run_link, 0.4))
        error, detail = await idle_stop.emergency_stop(sim.url, Drives(), holder=holder)
        assert error is None, error
        assert detail is not None and "OFF3" in detail
        assert holder.done()
        assert sim.regs(1)["CW"] == CW_EMERGENCY and sim.regs(2)["CW"] == CW_EMERGENCY
    finally:
        await run_link.close()
        await sim.endpoint.aclose()


async def test_a_run_that_keeps_the_port_past_the_bound_leaves_the_abort_not_sent(monkeypatch):
    monkeypatch.setattr(idle_stop, "LET_GO_S", 0.3)
    sim = await _rtu_rig()
    run_link = ModbusLink(sim.url, timeout=0.15)
    try:
        await run_link.connect()
        holder = asyncio.create_task(_holder(run_link, 30.0))
        t0 = asyncio.get_running_loop().time()
        error, detail = await idle_stop.emergency_stop(sim.url, Drives(), holder=holder)
        waited = asyncio.get_running_loop().time() - t0
        assert detail is None and error is not None
        assert error.startswith("emergency stop NOT sent") and "still holds" in error, error
        assert idle_stop.ESTOP in error
        assert 0.3 <= waited < 5.0, waited
        assert sim.regs(1)["CW"] != CW_EMERGENCY and sim.regs(2)["CW"] != CW_EMERGENCY
        holder.cancel()
        await asyncio.wait([holder])
    finally:
        await run_link.close()
        await sim.endpoint.aclose()


async def test_without_a_run_the_port_held_elsewhere_is_reported_at_once():
    sim = await _rtu_rig()
    other = ModbusLink(sim.url, timeout=0.15)
    try:
        await other.connect()  # e.g. a terminal program left on the port
        t0 = asyncio.get_running_loop().time()
        error, detail = await idle_stop.emergency_stop(sim.url, Drives())
        assert asyncio.get_running_loop().time() - t0 < 2.0
        assert detail is None and error is not None and error.startswith("emergency stop NOT sent"), error
    finally:
        await other.close()
        await sim.endpoint.aclose()
