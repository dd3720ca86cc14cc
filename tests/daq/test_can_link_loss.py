"""A CAN link that fails mid-run (the serial-over-TCP gateway gone, as the simulator's bus
between processes): said once, the event loop left alone, the bus opened again once it is back.

python-can's Notifier on the loop raised from the loop's callback every time the closed
connection was readable: about 22000 tracebacks a second with the loop busy on nothing else.
Real parts: the simulator's CAN hub over TCP, python-can's serial interface on both sides.
"""

from __future__ import annotations

import asyncio
import logging
import threading
import time

import can
import pytest

from daq.aux import LOST_AFTER, AuxSensors
from daq.can_reader import RETRY_MAX_S
from sim.can_tcp import CanTcpHub

pytestmark = pytest.mark.timeout(60)

HEARTBEAT = can.Message(arbitration_id=0x701, data=b"\x05", is_extended_id=False)


class Node:
    """A sensor node on the hub sending its operational heartbeat every 0.1 s from a thread."""

    def __init__(self, url: str):
        self.bus = can.Bus(interface="serial", channel=url)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._beat, daemon=True)
        self._thread.start()

    def _beat(self) -> None:
        while not self._stop.wait(0.1):
            try:
                self.bus.send(HEARTBEAT)
            except (can.CanError, OSError):
                return

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(2)
        self.bus.shutdown()


async def _until(pred, timeout: float) -> float:
    t0 = time.monotonic()
    while not pred():
        assert time.monotonic() - t0 < timeout, "condition not met in time"
        await asyncio.sleep(0.02)
    return time.monotonic() - t0


async def _watch_loop(seconds: float) -> float:
    """The longest gap (s) between 10 ms sleeps of the loop over ``seconds``."""
    worst, last, end = 0.0, time.monotonic(), time.monotonic() + seconds
    while time.monotonic() < end:
        await asyncio.sleep(0.01)
        now = time.monotonic()
        worst, last = max(worst, now - last), now
    return worst


async def test_a_lost_can_link_is_said_once_and_opened_again_when_back(caplog):
    caplog.set_level(logging.DEBUG)
    hub = await CanTcpHub().__aenter__()
    port = hub.port
    node = Node(hub.url)
    try:
        async with AuxSensors(hub.url, interface="serial") as aux:
            await _until(lambda: aux.latest().operational, 5.0)
            caplog.clear()
            await hub.aclose()  # the gateway goes: every connection closed
            node.stop()
            cpu0 = time.process_time()
            worst_gap = await _watch_loop(2.0)
            cpu = time.process_time() - cpu0
            assert aux.latest().node_lost and aux.link_drops == 1
            loud = [r for r in caplog.records if r.levelno >= logging.WARNING]
            assert len(loud) == 1 and "CAN link" in loud[0].getMessage(), [r.getMessage() for r in loud]
            assert worst_gap < 0.25, worst_gap  # a spinning loop read ~40 ms here; idle ~11 ms
            assert cpu < 0.8, cpu  # the traceback flood took the whole 2 s of a core

            hub = await CanTcpHub(port=port).__aenter__()  # the gateway is back on its address
            node = Node(hub.url)
            waited = await _until(lambda: aux.latest().operational, 2 * RETRY_MAX_S + LOST_AFTER)
            assert aux.link_drops == 1 and aux.link_error is None and aux.latest().link_error is None
            assert any("open again" in r.getMessage() for r in caplog.records), waited
    finally:
        node.stop()
        await hub.aclose()
