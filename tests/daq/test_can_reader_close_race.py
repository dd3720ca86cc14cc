"""A CAN bus opened again is never left open: one that opens while the reader closes is shut
down, and so is one whose node filters cannot be set (a serial adapter or a socket held at each
attempt: the next run could not open it).

Real parts: python-can's ``virtual`` bus (read by the reader's thread); the adapter's open is
made to take until the reader is closed, the filters made to fail (no real part does either on
cue)."""

from __future__ import annotations

import threading

import can
import pytest

from daq import can_reader
from daq.can_reader import CanReader
from support.polling import until

pytestmark = pytest.mark.timeout(30)


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
    await until(
        lambda: reader.error is not None and opening.is_set(), 5.0, "the reader opening the bus again", every=0.01
    )
    assert reader.close() is None  # nothing open to hand back: the failed bus is shut down already
    release.set()
    await until(lambda: bool(reopened), 5.0, "the open returning", every=0.01)
    await until(lambda: reopened[0]._is_shutdown, 5.0, "the bus opened after close shut down", every=0.01)


async def test_a_bus_whose_filters_cannot_be_set_is_shut_down(monkeypatch):
    """Opened again every few seconds while its link is down: a bus left open at each failed
    attempt would hold a socket or a port each time. (The filter's failure is injected: a real
    interface gives it only in a broken state.)"""
    from daq.aux import AuxSensors
    from daq.errors import DaqError

    opened: list[can.BusABC] = []

    def refuse(self, filters=None):
        if filters is None:  # the bus's own constructor: no filter yet
            return
        opened.append(self)
        raise can.CanOperationError("filter refused")

    monkeypatch.setattr(can.BusABC, "set_filters", refuse)
    aux = AuxSensors("filters", interface="virtual")
    with pytest.raises(DaqError, match="cannot set the node's filters"):
        aux.open()
    assert len(opened) == 1 and opened[0]._is_shutdown
