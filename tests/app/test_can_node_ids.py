"""The interlocks name the CAN ids of the node the rig reads ([transports] can_node_id), derived from
its node id (docs/protocols/can-node.md: function base + node id), not node 1's: a lab whose
node is 5 is told of its heartbeat 0x705, pressure frame 0x285 and status frame 0x385.

Real parts: the simulator's CAN node (sim/can_node.py) as node 5 on python-can's `virtual` bus, read
by daq.aux.AuxSensors; what the simulator's node cannot send (a pre-operational heartbeat, a
heartbeat without process data) is sent as real frames on the same bus."""

from __future__ import annotations

import asyncio
import contextlib
import itertools
from collections.abc import AsyncIterator

import can
import pytest

from daq.aux import AuxSensors, Frame, can_id_text
from orbitrig.config import Interlocks
from orbitrig.run import interlocks
from sim.can_node import CanNode

pytestmark = pytest.mark.timeout(30)
NODE = 5
_names = itertools.count()
#: what the node reports (SI): the supply and recess pressures of the demo matrix, the pump on
STATE = {
    "t_recess": 313.15,
    "t_groove": 313.15,
    "t_supply": 313.15,
    "flow": 2e-5,
    "p_supply": 1.207e6,
    "p_recess": (0.483e6,) * 4,
    "pump_off": False,
}


@contextlib.asynccontextmanager
async def _node_read() -> AsyncIterator[tuple[CanNode, AuxSensors, can.BusABC]]:
    """The simulator's node `NODE` sending, AuxSensors reading it as `NODE`, and a bus of the
    test's own on the same channel (for frames the node cannot send)."""
    channel = f"can-node-ids-{next(_names)}"
    node = CanNode(channel, lambda: STATE, node_id=NODE)
    sending = asyncio.create_task(node.run())
    other = can.Bus(interface="virtual", channel=channel)
    try:
        async with AuxSensors(channel, interface="virtual", node_id=NODE) as aux:
            yield node, aux, other
    finally:
        sending.cancel()
        await asyncio.gather(sending, return_exceptions=True)
        other.shutdown()


async def _heartbeats(bus: can.BusABC, state: int, n: int) -> None:
    """`n` heartbeats `state` of node `NODE`, 0.1 s apart."""
    for _ in range(n):
        bus.send(can.Message(arbitration_id=Frame.HEARTBEAT + NODE, data=[state], is_extended_id=False))
        await asyncio.sleep(0.1)


def _messages(aux: AuxSensors) -> str:
    """The interlocks' trips for the node's latest state, the point's pressures verified."""
    trips = interlocks.check(aux.latest(), None, Interlocks(), pressure_armed=True)
    return " | ".join(t.message for t in trips)


def test_the_node_s_can_ids_are_its_function_bases_plus_its_node_id():
    assert [can_id_text(f, NODE) for f in Frame] == ["0x185", "0x285", "0x385", "0x705"]
    assert can_id_text(Frame.HEARTBEAT, 1) == "0x701"


async def test_a_sensor_fault_names_the_status_frame_of_the_configured_node():
    async with _node_read() as (node, aux, _):
        await aux.heard()
        node.sensor_fault = True
        await asyncio.sleep(0.3)
        said = _messages(aux)
    assert "reports a faulty sensor (status 0x385 bit 0)" in said, said
    assert "0x381" not in said


async def test_a_pre_operational_node_names_its_own_heartbeat():
    async with _node_read() as (node, aux, bus):
        node.heartbeat_lost = True  # only the test's heartbeats: pre-operational
        await _heartbeats(bus, 0x7F, 3)
        said = _messages(aux)
    assert "not operational (heartbeat 0x705 state 0x7f)" in said, said
    assert "0x701" not in said


async def test_a_node_without_process_data_names_its_own_pressure_frame():
    async with _node_read() as (node, aux, bus):
        node.silent = True  # no frame of the node's own: the test's operational heartbeats alone
        await _heartbeats(bus, 0x05, 3)
        assert aux.latest().operational
        said = _messages(aux)
    assert "sends no pressure frame 0x285" in said, said
    assert "0x281" not in said
