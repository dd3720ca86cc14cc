"""A connection opened on a busy host: the link's connect bound is its own, not the request's.

A request that times out drops its TCP connection, and the next request (a stop's word, say)
connects again. pymodbus bounds a connect by the client's timeout, the request timeout (0.1 s
here, 0.15 s on the rig); on a host busy enough to hold the loop that long as the connect
begins, the connect failed (DriveConnectError: "cannot connect", not retried by a stop) though
the drives were there: the stop's words were left to the poll's next reconnect, the drives'
comm-loss watchdog (0.5 s here) tripping both meanwhile. Now a connect has the link's own bound,
the request timeout + 0.5 s. The loop is held 0.3 s right as the connect begins (the load a real
part cannot be made to put there); the simulator's drives behind a real Modbus TCP server."""

from __future__ import annotations

import asyncio
import time

import pytest

from drives.drive import Drive
from drives.errors import DriveTimeoutError
from drives.connection import CONNECT_EXTRA_S
from drives.link import ModbusLink
from drives.stop import send_stop
from support.drives_testkit import CW_EMERGENCY, CW_RUN

pytestmark = pytest.mark.timeout(30)

HELD_S = 0.3  # the loop held as the connect begins: 3 request timeouts, within the connect's 0.6 s


def _hold_the_loop() -> None:
    asyncio.get_running_loop().call_soon(time.sleep, HELD_S)


async def test_a_connect_held_up_longer_than_the_request_timeout_still_opens(tcp_sim):
    link = ModbusLink(tcp_sim.url, timeout=0.1)
    try:
        _hold_the_loop()
        await link.connect()
        assert link.connected and link.connects == 1
        tcp_sim.endpoint.drop_next(1)  # an answer still has the request timeout, not the connect's
        t0 = time.monotonic()
        with pytest.raises(DriveTimeoutError, match="no answer within 0.1 s"):
            await link.read(1, 0, 7)
        assert time.monotonic() - t0 < 0.1 + CONNECT_EXTRA_S, time.monotonic() - t0
    finally:
        await link.close()


async def test_a_stop_on_a_new_connection_gets_through_a_busy_moment(tcp_sim):
    for dev in (1, 2):
        tcp_sim.models[dev].write(0, [CW_RUN])
    async with ModbusLink(tcp_sim.url, timeout=0.1) as link:
        drives = (Drive(link, 1, "spin", bidirectional=False), Drive(link, 2, "orbit", bidirectional=True))
        for d in drives:
            await d.read_parameters()
        await link.close()  # as after a request that timed out: the stop connects again
        _hold_the_loop()
        errors = await send_stop(drives, emergency=True)
    assert errors == [] and link.connects == 2, errors
    assert tcp_sim.regs(1)["CW"] == tcp_sim.regs(2)["CW"] == CW_EMERGENCY
