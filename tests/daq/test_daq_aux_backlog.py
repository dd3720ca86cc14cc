"""A loop held late (a starved host) finds the node's frames of that while queued on the bus's
descriptor. They were read one a turn of the loop, and a check looking after the first (the
run's interlock supervisor samples every 0.05 s) judged the node lost by a heartbeat 1.7 s old
while the node's newer heartbeat lay unread behind it: a suspension for our own reader's delay.
Now a readable descriptor is read until nothing waits on it.

Real parts: python-can's `serial` interface over TCP (as the simulator's CAN hub is reached),
its peer a plain socket sending the node's frames in python-can's serial framing; the loop is
held by a blocking sleep (the load a real part cannot be made to put there)."""

from __future__ import annotations

import asyncio
import socket
import struct
import time

import pytest

from daq.aux import LOST_AFTER, AuxSensors

pytestmark = pytest.mark.timeout(30)

HELD_S = LOST_AFTER + 0.2  # s the loop is held: the last heartbeat read is older than LOST_AFTER
ROUNDS = 17  # the node's 0.1 s rounds sent while the loop was held; a heartbeat every 5th


def _serial_frame(can_id: int, data: bytes) -> bytes:
    """One frame of python-can's serial interface: 0xAA, timestamp ms, DLC, identifier, data, 0xBB."""
    return b"\xaa" + struct.pack("<IBI", 0, len(data), can_id) + data + b"\xbb"


def _round(k: int) -> bytes:
    """The node's round `k` (node 1): its three process-data frames, a heartbeat first every 5th."""
    heartbeat = _serial_frame(0x701, b"\x05") if k % 5 == 0 else b""
    return heartbeat + b"".join(_serial_frame(i, bytes(8 if i != 0x381 else 4)) for i in (0x181, 0x281, 0x381))


async def test_the_frames_queued_while_the_loop_was_held_are_read_before_the_node_is_judged():
    with socket.create_server(("127.0.0.1", 0)) as server:
        url = f"socket://127.0.0.1:{server.getsockname()[1]}"
        async with AuxSensors(url, interface="serial") as aux:
            node, _ = server.accept()  # the bus connected as it opened
            with node:
                node.sendall(_round(0))
                await asyncio.wait_for(aux.heard(), 10)
                assert not aux.latest().node_lost
                received = aux.frames_received
                time.sleep(HELD_S)  # the loop held: the node sends on time meanwhile
                node.sendall(b"".join(_round(k) for k in range(1, ROUNDS + 1)))  # last heartbeat: round 15
                arrival = aux.arrival
                await asyncio.wait_for(arrival.wait(), 10)  # woken by the first frame of the backlog read
                s = aux.latest()
                assert not s.node_lost and s.operational, s.heartbeat_age  # was lost: heartbeat 1.7 s old
                assert s.heartbeat_age < LOST_AFTER, s.heartbeat_age
                assert aux.frames_received - received == ROUNDS * 3 + 3, aux.frames_received - received  # all at once
