"""The CAN bus link itself failing (a USB adapter pulled, an interface gone down, here the
serial-over-TCP hub the simulator uses closing): the bus is read no more, the failure is said
once, and the node counts as lost at once (the interlocks' CAN node loss), instead of the event
loop that polls the drives calling a reader that raises on every turn.

Real parts: python-can's `serial` interface on the simulator's CAN hub (sim.can_tcp), a second
node on it sending the heartbeat."""

from __future__ import annotations

import asyncio
import time

import can
import pytest

from daq.aux import AuxSensors
from sim.can_tcp import CanTcpHub
from support.polling import until

pytestmark = pytest.mark.timeout(30)
HEARTBEAT = can.Message(arbitration_id=0x701, data=b"\x05", is_extended_id=False)


async def test_a_can_link_that_fails_is_read_no_more_and_the_node_counts_as_lost(caplog):
    loop = asyncio.get_running_loop()
    unhandled: list[dict] = []  # what the loop's exception handler got: a callback that raised
    loop.set_exception_handler(lambda _loop, context: unhandled.append(context))
    try:
        async with CanTcpHub() as hub:
            node = can.Bus(interface="serial", channel=hub.url)
            try:
                async with AuxSensors(hub.url, interface="serial") as aux:
                    await asyncio.sleep(0.2)  # the hub accepts both connections
                    node.send(HEARTBEAT)
                    await until(lambda: not aux.latest().node_lost, 5, "the node's heartbeat read", every=0.01)
                    await hub.aclose()  # the bus link fails under the reader
                    t_lost = time.monotonic()
                    await until(lambda: aux.latest().node_lost, 3.0, "the node lost with its link", every=0.01)
                    lost_after = time.monotonic() - t_lost
                    await asyncio.sleep(0.5)  # the loop turns on with the failed link
                    assert unhandled == [], f"{len(unhandled)} callbacks raised, e.g. {unhandled[0]['message']}"
                    assert lost_after < 0.5, lost_after  # the heartbeat's own age (1.5 s) not waited for
                    assert aux.link_error is not None and "could not read" in aux.link_error, aux.link_error
                    assert aux.latest().link_error == aux.link_error  # what the interlock's trip says
                    failed = [r for r in caplog.records if "CAN link" in r.getMessage()]
                    assert len(failed) == 1, [r.getMessage() for r in failed]
            finally:
                node.shutdown()
    finally:
        loop.set_exception_handler(None)
