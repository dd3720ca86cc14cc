"""The simulator's CAN bus between processes (python-can `serial` framing over TCP)
and what `orbitrig sim` says it serves."""

from __future__ import annotations

import asyncio
import json
import os
import signal
import time

import can
import pytest
from support.cli_helpers import orbitrig_started, reaped

from daq.aux import AuxSensors
from sim.can_tcp import CanTcpHub, split_frames


def _frame(can_id: int, data: bytes) -> bytes:
    return bytes([0xAA, 0, 0, 0, 0, len(data)]) + can_id.to_bytes(4, "little") + data + bytes([0xBB])


def test_split_frames_skips_junk_and_keeps_a_partial_frame():
    a, b = _frame(0x181, bytes(range(8))), _frame(0x701, b"\x05")
    buf = bytearray(b"\x00\x13" + a + b"\xaa\x00" + b + b[:7])
    # "\xaa\x00" then b: a false start whose would-be end byte is not 0xBB, skipped byte by byte
    frames = split_frames(buf)
    assert frames == [a, b]
    assert bytes(buf) == b[:7]
    buf += b[7:]
    assert split_frames(buf) == [b] and buf == bytearray()


def test_split_frames_drops_an_oversized_dlc():
    bad = bytes([0xAA, 0, 0, 0, 0, 9]) + bytes(14)
    good = _frame(0x281, bytes(8))
    buf = bytearray(bad + good)
    assert split_frames(buf) == [good]


async def test_hub_delivers_every_frame_to_the_other_nodes_only():
    async with CanTcpHub() as hub:
        sender = can.Bus(interface="serial", channel=hub.url)
        readers = [can.Bus(interface="serial", channel=hub.url, timeout=0.05) for _ in range(2)]
        try:
            await asyncio.sleep(0.1)  # the hub accepts the connections
            sent = [
                can.Message(arbitration_id=0x181 + i, data=bytes([i] * (i % 9)), is_extended_id=False)
                for i in range(20)
            ]
            for msg in sent:
                sender.send(msg)
            for bus in readers:
                got = []
                deadline = time.monotonic() + 5
                while len(got) < len(sent) and time.monotonic() < deadline:
                    msg = await asyncio.to_thread(bus.recv, 0.1)
                    if msg is not None:
                        got.append((msg.arbitration_id, bytes(msg.data)))
                assert got == [(m.arbitration_id, bytes(m.data)) for m in sent]
            assert await asyncio.to_thread(sender.recv, 0.2) is None  # a node does not hear itself
            assert hub.frames_relayed == len(sent)
        finally:
            for bus in (sender, *readers):
                bus.shutdown()


@pytest.fixture
def sim_process():
    with reaped(
        orbitrig_started(
            "sim", "--modbus-port", "0", "--adc-port", "0", "--can-port", "0", "--speedup", "10", stdin=None
        )
    ) as p:
        yield p


async def test_orbitrig_sim_says_what_it_serves_and_its_can_node_reaches_another_process(sim_process):
    line = await asyncio.to_thread(sim_process.stdout.readline)
    ep = json.loads(line)
    assert ep["can"].startswith("socket://127.0.0.1:")
    async with AuxSensors(ep["can"], interface="serial") as aux:  # this process is not the simulator's
        deadline = time.monotonic() + 10
        while not (aux.frames_received >= 8 and aux.latest().operational) and time.monotonic() < deadline:
            await asyncio.sleep(0.1)  # the heartbeat comes every 0.5 s
        assert aux.frames_received >= 8
        assert aux.frames_malformed == 0
        state = aux.latest()
        assert state.operational  # heartbeat 0x05, not lost
        assert state.p_supply > 0 and 0 < state.beta < 1
        assert not state.stale("p_supply") and not state.stale("t_supply")
    os.kill(sim_process.pid, signal.SIGINT)
    rc = await asyncio.to_thread(sim_process.wait, 20)
    err = sim_process.stderr.read()
    assert rc == 0, err
    for what in (
        "drives",
        ep["modbus"],
        "A/D board",
        ep["adc"],
        ep["adc_pty"],
        "CAN node",
        "interface 'serial'",
        ep["can"],
        "Ctrl-C",
    ):
        assert what in err, what
    assert f'can_interface = "serial", can_channel = "{ep["can"]}"' in err
    # the keys go into a lab's rig.toml, never the shipped defaults the README says are not edited
    assert "In a lab's rig.toml (`orbitrig init DIR`; the shipped config/ is never edited) [transports]:" in err
    assert "In config/rig.toml" not in err
    assert "Traceback" not in err


async def test_orbitrig_sim_says_nothing_of_a_client_that_hangs_up_before_its_answer(sim_process):
    """A client that closes its connection with a request unanswered (the drives' poll read
    given up for a stop) is routine: pymodbus' error with its frames in hex stays off stderr."""
    ep = json.loads(await asyncio.to_thread(sim_process.stdout.readline))
    host, port = ep["modbus"].removeprefix("tcp://").rsplit(":", 1)
    for tid in range(1, 21):  # each read of the spin drive's 7 status registers, then gone
        _, writer = await asyncio.open_connection(host, int(port))
        writer.write(bytes([0, tid, 0, 0, 0, 6, 1, 3, 0, 0, 0, 7]))
        await writer.drain()
        writer.close()
        await writer.wait_closed()
    await asyncio.sleep(0.5)  # the simulator's answers find the connections closed
    os.kill(sim_process.pid, signal.SIGINT)
    rc = await asyncio.to_thread(sim_process.wait, 20)
    err = sim_process.stderr.read()
    assert rc == 0, err
    assert "Cancel send" not in err and ">>>>>" not in err, err
    assert "Ctrl-C ends it" in err
