"""An abort's stop words do not wait for the poll's read in flight on the same link.

The worst case is a drive that never answers that read: the stop words used to wait the whole
request timeout for it. On TCP the read now gives way (drives/link.py): its connection is dropped
and the stop goes out at once on a new one, the skipped poll counted as no failure. A write in
flight is still answered (or timed out) first, and on RTU, one exchange at a time on the line,
the stop waits for the read: timeout plus the settle time after a missed answer, the bound the
README gives. Real parts: the simulator's drives behind a real Modbus server, the read dropped
by the server itself (`drop_next`)."""

from __future__ import annotations

import asyncio

import pytest
from support.drives_testkit import CW_EMERGENCY, RPM, open_rig

from drives import registers as R
from drives.errors import DriveGaveWay, DriveTimeoutError
from drives.limits import DriveLimits
from drives.link import ModbusLink

pytestmark = pytest.mark.timeout(30)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM)
TIMEOUT = 0.5  # s per request: long enough that waiting for it cannot pass for not waiting


async def _unanswered(sim) -> None:
    """Until the next request (the poll's read, or a write just started) reached the
    simulator and went unanswered: it is in flight, and stays so for the request timeout."""
    sim.endpoint.drop_next(1)
    loop = asyncio.get_running_loop()
    t_end = loop.time() + 5.0
    while sim.endpoint.requests_to_drop:  # the server's own count of requests left to drop
        assert loop.time() < t_end, "no request reached the simulator"
        await asyncio.sleep(0.001)


async def _both_stopped_after(sim, t0: float) -> float:
    """Seconds from `t0` until both drives hold the emergency stop word."""
    loop = asyncio.get_running_loop()
    while not (sim.regs(1)["CW"] == CW_EMERGENCY and sim.regs(2)["CW"] == CW_EMERGENCY):
        assert loop.time() - t0 < 5.0, "stop words not delivered"
        await asyncio.sleep(0.001)
    return loop.time() - t0


async def _turning(rig) -> None:
    await rig.set_speeds(600 * RPM, 300 * RPM)
    await rig.wait_settled(hold=0.05, timeout=10)


async def _emergency_stop(rig, sim) -> float:
    """The emergency stop sent now: seconds until both drives hold its word (it reports no failure)."""
    t0 = asyncio.get_running_loop().time()
    stop = rig.stop_now(emergency=True)
    took = await _both_stopped_after(sim, t0)
    assert await stop == []
    return took


async def test_on_tcp_the_stop_does_not_wait_for_an_unanswered_poll_read(tcp_sim):
    sim = tcp_sim
    async with open_rig(sim, LIMITS, timeout=TIMEOUT, poll_interval=0.1, comm_loss_timeout=2.0) as rig:
        await _turning(rig)
        failures, connects = rig.state.poll_failures, rig.link.connects
        await _unanswered(sim)
        took = await _emergency_stop(rig, sim)
        await asyncio.sleep(0.3)  # polls go on after the one given up
        state, reconnects = rig.state, rig.link.connects - connects  # (the way out's stop may add one)
    assert took < TIMEOUT / 2, f"the stop waited {took:.3f} s for the read in flight"
    assert state.link_ok and state.poll_failures == failures, state  # given up, not failed
    assert reconnects == 1  # the read's connection dropped, the stop on a new one


async def test_on_tcp_a_write_in_flight_is_answered_before_the_stop(tcp_sim):
    """A write is never given up: on another connection the stop could overtake it."""
    sim = tcp_sim
    async with open_rig(sim, LIMITS, timeout=TIMEOUT, poll_interval=0.1, comm_loss_timeout=2.0) as rig:
        await _turning(rig)
        write = asyncio.create_task(rig.link.write(1, R.REF2, [0]))  # REF2: unused, reads back what was written
        await _unanswered(sim)
        took = await _emergency_stop(rig, sim)
        with pytest.raises(DriveTimeoutError):
            await write
    assert TIMEOUT / 2 < took < TIMEOUT + 1.0, took  # waited for it (the read that gives way: < TIMEOUT / 2)


@pytest.mark.parametrize("sim", ["rtu"], indirect=True)
async def test_on_rtu_the_stop_waits_for_the_read_then_the_settle_time(sim):
    async with open_rig(sim, LIMITS, timeout=TIMEOUT, poll_interval=0.1, comm_loss_timeout=2.0) as rig:
        await _turning(rig)
        await _unanswered(sim)
        took = await _emergency_stop(rig, sim)
    settle = min(TIMEOUT, 0.05)  # drives.rtu.RtuLine's default
    assert TIMEOUT / 2 < took < TIMEOUT + settle + 1.0, took


async def test_a_read_that_was_connecting_when_the_stop_came_gives_way_too(tcp_sim):
    """The read had the link but was still opening its connection when the stop's word asked
    for it: it gives way as soon as its exchange would start, not after its answer."""
    sim = tcp_sim
    async with ModbusLink(sim.url, timeout=TIMEOUT) as link:
        await link.close()  # the next request connects first
        read = asyncio.create_task(link.read(1, 0, 7, gives_way=True))
        await asyncio.sleep(0)  # the read has the link and waits for its connection
        assert link.connects == 1 and not link.connected  # the first one, on entry
        sim.endpoint.drop_next(1)  # were it sent, the read would go unanswered
        loop = asyncio.get_running_loop()
        t0 = loop.time()
        await link.write(1, R.CW, [CW_EMERGENCY], urgent=True)
        took = loop.time() - t0
        with pytest.raises(DriveGaveWay):
            await read
    assert took < TIMEOUT / 2, took
    assert sim.regs(1)["CW"] == CW_EMERGENCY
