"""A CAN reader closed while it is opening its failed bus again: the bus that open still hands
back is shut down, not left open (a serial adapter or a socket held: the next run could not
open it).

Real parts: python-can's ``virtual`` bus (read by the reader's thread); the adapter's open is
made to take until the reader is closed (no real part opens that slowly on cue)."""

from __future__ import annotations

import asyncio
import threading
import time

import can
import pytest

from daq import can_reader
from daq.can_reader import CanReader

pytestmark = pytest.mark.timeout(30)


async def _until(pred, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not pred():
        assert time.monotonic() < deadline, f"not within {timeout} s: {what}"
        await asyncio.sleep(0.01)


async def test_a_bus_opened_again_while_the_reader_closes_is_shut_down(monkeypatch):
    monkeypatch.setattr(can_reader, "RETRY_S", 0.01)
    opening, release, reopened = threading.Event(), threading.Event(), []

    def reopen() -> can.BusABC:  # the adapter opens only once the reader is closed
        opening.set()
        release.wait(10)
        bus = can.Bus(interface="virtual", channel="close-race")
        reopened.append(bus)
        return bus

    first = can.Bus(interface="virtual", channel="close-race")
    reader = CanReader(first, reopen, lambda msg: None, "virtual:close-race")
    first.shutdown()  # the link fails under the reader's thread
    await _until(lambda: reader.error is not None and opening.is_set(), 5.0, "the reader opening the bus again")
    assert reader.close() is None  # nothing open to hand back: the failed bus is shut down already
    release.set()
    await _until(lambda: bool(reopened), 5.0, "the open returning")
    await _until(lambda: reopened[0]._is_shutdown, 5.0, "the bus opened after close shut down")
