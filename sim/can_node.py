"""The auxiliary sensor node of docs/protocols/can-node.md on a python-can bus.

Node id 1: 0x181 temperatures + flow, 0x281 supply + recess 1..3 pressures,
0x381 recess 4 + status, every 100 ms; heartbeat 0x701 every 500 ms. Periods
are wall time (communication timers do not follow the speed-up).
"""

from __future__ import annotations

import asyncio
import logging
import struct
import threading
import time
from typing import Any, Callable

import numpy as np

log = logging.getLogger(__name__)

HEARTBEAT_OPERATIONAL = 0x05
HEARTBEAT_PREOPERATIONAL = 0x7F
STATUS_SENSOR_FAULT, STATUS_PUMP_OFF = 0x01, 0x02


def _i16(v: float) -> int:
    return int(np.clip(round(v), -32768, 32767))


def _u16(v: float) -> int:
    return int(np.clip(round(v), 0, 65535))


def _centi_degc(kelvin: float) -> int:
    return _i16((kelvin - 273.15) * 100.0)


def _kpa(pa: float) -> int:
    return _u16(pa / 1000.0)


def encode_aux(state: dict, *, node_id: int = 1, sensor_fault: bool = False) -> list[tuple[int, bytes]]:
    """The three process-data frames (CAN id, payload) from SI values (see physics.aux_state):
    temperatures in 0.01 degC, flow in 0.01 L/min, pressures in kPa."""
    c, kpa = _centi_degc, _kpa
    p = state["p_recess"]
    status = (STATUS_SENSOR_FAULT if sensor_fault else 0) | (STATUS_PUMP_OFF if state["pump_off"] else 0)
    return [
        (
            0x180 + node_id,
            struct.pack(
                "<hhhH",
                c(state["t_recess"]),
                c(state["t_groove"]),
                c(state["t_supply"]),
                _u16(state["flow"] * 60000.0 * 100.0),
            ),
        ),
        (0x280 + node_id, struct.pack("<HHHH", kpa(state["p_supply"]), kpa(p[0]), kpa(p[1]), kpa(p[2]))),
        (0x380 + node_id, struct.pack("<HH", kpa(p[3]), status)),
    ]


#: wall s between two rounds of the node's frames (at any speed-up: the CAN periods stay in wall time)
FRAME_PERIOD_S = 0.1


class CanNode:
    """Transmits the node's frames on ``channel`` until cancelled.

    ``state`` returns the current physics.aux_state dict. Faults:
    ``heartbeat_lost`` (no heartbeats), ``silent`` (nothing at all),
    ``sensor_fault`` (status bit 0).
    """

    def __init__(
        self,
        channel: str,
        state: Callable[[], dict],
        *,
        interface: str = "virtual",
        node_id: int = 1,
        period: float = FRAME_PERIOD_S,
        heartbeat_period: float = 0.5,
    ):
        self.channel = channel
        self.interface = interface
        self._state = state
        self.node_id = node_id
        self.period = period
        self.heartbeat_period = heartbeat_period
        self.heartbeat_lost = False
        self.silent = False
        self.sensor_fault = False
        self.frames_sent = 0
        self._bus: Any = None  # can.BusABC once open

    def open(self) -> None:
        import can  # imported here: only the CAN node needs python-can

        self._bus = can.Bus(interface=self.interface, channel=self.channel)

    def _send(self, can_id: int, data: bytes) -> None:
        import can

        try:
            self._bus.send(can.Message(arbitration_id=can_id, data=data, is_extended_id=False))
            self.frames_sent += 1
        except can.CanError as err:
            log.warning("CAN send 0x%03X failed: %s", can_id, err)

    async def run(self) -> None:
        if self._bus is None:
            self.open()
        t0 = time.monotonic()
        k = 0
        every = max(1, round(self.heartbeat_period / self.period))
        try:
            while True:
                if not self.silent:
                    if k % every == 0 and not self.heartbeat_lost:
                        self._send(0x700 + self.node_id, bytes([HEARTBEAT_OPERATIONAL]))
                    for can_id, data in encode_aux(self._state(), node_id=self.node_id, sensor_fault=self.sensor_fault):
                        self._send(can_id, data)
                k += 1
                await asyncio.sleep(max(0.0, t0 + k * self.period - time.monotonic()))
        finally:
            self.close()

    def close(self) -> None:
        """Close the bus without blocking: python-can's `serial` bus over a TCP socket (pyserial's
        socket:// port) closes its socket at once, then sleeps 0.3 s "for quick reconnects", which
        would stall the event loop and every server on it; that close runs in a thread."""
        bus, self._bus = self._bus, None
        if bus is not None:
            threading.Thread(target=bus.shutdown, name="can-node-close", daemon=True).start()
