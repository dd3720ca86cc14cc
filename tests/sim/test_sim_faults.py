"""Fault injection, each seen from outside through the real transports."""

from __future__ import annotations

import asyncio
import math
import os
import struct
import time

import pytest

from sim.adc_server import DEFAULT_BACKLOG
from sim.config import SimConfig
from sim.rig import SimRig
from support.sim_reader import parse, read_tcp, revolutions

ORBIT = 2 * math.pi * 20.0


async def stream_with(rig: SimRig, fault: str, *, revs: int = 20, **kw) -> bytes:
    """The TCP stream with `fault` injected once a few whole frames have come (a fault before the
    reader is connected goes to nobody; frames before it show its gap), read until `revs` complete
    revolutions after the injection. Not a fixed 0.05 s before it: a loaded machine stretched that
    sleep past the 20 revolutions the reader waited for, and the fault fell after the stream read."""
    reader, writer = await asyncio.open_connection("127.0.0.1", rig.adc_server.port)
    buf, t_end = bytearray(), time.monotonic() + 20
    try:
        while len(parse(bytes(buf))[0]) < 3:
            assert time.monotonic() < t_end, "no frames within 20 s"
            buf += await asyncio.wait_for(reader.read(1 << 16), 5)
        rig.inject(fault, **kw)
        before = len(revolutions(parse(bytes(buf))[0]))
        while len(revolutions(parse(bytes(buf))[0])) < before + revs:
            assert time.monotonic() < t_end, f"not {revs} revolutions after the fault within 20 s"
            buf += await asyncio.wait_for(reader.read(1 << 16), 5)
    finally:
        writer.close()
    return bytes(buf)


def seq_gaps(frames) -> list[int]:
    return [(b.seq - a.seq - 1) & 0xFFFF for a, b in zip(frames, frames[1:]) if b.seq != (a.seq + 1) & 0xFFFF]


@pytest.fixture
async def rig():
    async with SimRig(SimConfig(), speedup=5.0, can_channel=None) as r:
        r.local_control(spin=150.0, orbit=ORBIT)
        yield r


async def test_corrupted_bytes_fail_the_crc(rig):
    data = await stream_with(rig, "corrupt_bytes", count=2)
    frames, bad, _ = parse(data)
    assert seq_gaps(frames) in ([2], [1, 1])  # exactly the two corrupted frames are unreadable
    assert bad >= 1
    assert not any(f.flags & 0x02 for f in frames)  # the board lost nothing
    assert len(revolutions(frames)) >= 4


async def test_dropped_frames_leave_a_seq_gap_and_overrun(rig):
    data = await stream_with(rig, "drop_frames", count=3)
    frames, bad, _ = parse(data)
    assert bad == 0 and seq_gaps(frames) == [3]
    i = next(i for i, (a, b) in enumerate(zip(frames, frames[1:])) if b.seq != (a.seq + 1) & 0xFFFF)
    assert frames[i + 1].flags & 0x02  # OVERRUN on the first frame after the loss
    assert sum(bool(f.flags & 0x02) for f in frames) == 1
    # the revolution with the hole is not complete: revolutions skip its rev number
    revs = [r for r, _, _ in revolutions(frames)]
    assert frames[i].rev not in revs or frames[i + 1].rev not in revs


async def test_missing_trigger(rig):
    data = await stream_with(rig, "missing_trigger", count=1)
    frames, bad, _ = parse(data)
    assert bad == 0 and seq_gaps(frames) == []
    at_zero = [f for f in frames if f.first_slot == 0]
    missed = [f for f in at_zero if not f.flags & 0x01]
    assert len(missed) == 1
    before = frames[frames.index(missed[0]) - 1]
    assert missed[0].rev == before.rev  # no trigger, no new revolution number
    revs = [r for r, _, _ in revolutions(frames)]
    assert revs == sorted(set(revs)) and missed[0].rev in revs  # the rev before it was complete


async def test_stalled_board_clock(rig):
    frames, _, _ = parse(await read_tcp(rig.adc_server.port, min_revs=2))
    assert frames[1].t_us > frames[0].t_us  # the clock runs
    rig.inject("stall_clock")
    # read from a link opened after the stall: a busy machine may hand a reader that was connected
    # before it a whole backlog of frames made before it (12 revolutions arrived before the fault)
    frames, _, _ = parse(await read_tcp(rig.adc_server.port, min_revs=12))
    stamps = [f.t_us for f in frames]
    assert len(frames) >= 10 and stamps[-1] == stamps[-2] == stamps[-10] == stamps[0], stamps
    rig.inject("clear")
    frames, _, _ = parse(await read_tcp(rig.adc_server.port, min_revs=2))
    assert frames[-1].t_us > frames[0].t_us


async def test_closed_tcp_link_then_reconnect(rig):
    reader, writer = await asyncio.open_connection("127.0.0.1", rig.adc_server.port)
    assert await reader.read(100)
    rig.inject("close_adc_link", reopen_after=0.2)
    t0 = time.monotonic()
    while await asyncio.wait_for(reader.read(1 << 16), 2.0):
        assert time.monotonic() - t0 < 2.0
    writer.close()  # EOF seen: the server closed the link
    frames, bad, _ = parse(await read_tcp(rig.adc_server.port, min_revs=2))
    assert bad == 0 and len(revolutions(frames)) >= 2


async def test_pty_hangup_then_reopen(rig):
    path = rig.adc_pty_path
    fd = os.open(path, os.O_RDONLY | os.O_NOCTTY | os.O_NONBLOCK)
    try:
        rig.inject("close_adc_link", reopen_after=0.3)
        await asyncio.sleep(0.05)
        hung_up = False
        for _ in range(200):  # a hung-up line reads as EOF or fails with EIO
            try:
                if os.read(fd, 1 << 16) == b"":
                    hung_up = True
                    break
            except BlockingIOError:
                await asyncio.sleep(0.01)
            except OSError:
                hung_up = True
                break
        assert hung_up
    finally:
        os.close(fd)
    assert rig.adc_pty_path is None
    await asyncio.sleep(0.5)
    assert rig.adc_pty_path is not None and os.path.exists(rig.adc_pty_path)


def modbus_read(port: int, unit: int, address: int, count: int, timeout: float = 1.0) -> list[int]:
    """Raw Modbus TCP read holding registers (FC 03), written from the protocol, big-endian."""
    import socket

    with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
        s.sendall(struct.pack(">HHHBBHH", 7, 0, 6, unit, 3, address, count))
        head = s.recv(9)
        tid, proto, length, uid, fc, nbytes = struct.unpack(">HHHBBB", head)
        assert (tid, proto, uid, fc) == (7, 0, unit, 3)
        body = b""
        while len(body) < nbytes:
            body += s.recv(nbytes - len(body))
        return list(struct.unpack(f">{count}H", body))


async def test_drive_trip_and_modbus_timeout(rig):
    port = int(rig.modbus_url.rsplit(":", 1)[1])
    loop = asyncio.get_running_loop()
    rig.inject("drive_trip", drive=2, code=2310)
    sw, act, torque, fault = await loop.run_in_executor(None, modbus_read, port, 2, 3, 4)
    assert fault == 2310 and sw & (1 << 3)  # TRIPPED
    assert (await loop.run_in_executor(None, modbus_read, port, 1, 6, 1)) == [0]  # spin drive fine
    rig.inject("modbus_timeout", on=True)
    with pytest.raises(OSError):  # socket.timeout: no answer at all
        await loop.run_in_executor(None, modbus_read, port, 1, 3, 1, 0.5)
    rig.inject("clear")
    assert len(await loop.run_in_executor(None, modbus_read, port, 1, 3, 1)) == 1
    with pytest.raises(ValueError, match="unknown fault"):
        rig.inject("gremlins")


async def test_slow_reader_loses_whole_frames_and_never_blocks_the_loop():
    import socket

    async with SimRig(SimConfig(), speedup=50.0, can_channel=None) as rig:
        rig.local_control(spin=150.0, orbit=2 * math.pi * 40)  # 0.72 M samples/s, 1.8 MB/s
        sock = socket.socket()
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        sock.connect(("127.0.0.1", rig.adc_server.port))
        reader, writer = await asyncio.open_connection(sock=sock)
        loop = asyncio.get_running_loop()
        while not rig.adc_server.clients:
            await asyncio.sleep(0.01)
        for client in rig.adc_server.clients:  # a link with small kernel buffers
            client.writer.transport.get_extra_info("socket").setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 4096)
        (sink,) = rig.adc_server.clients
        lags = []
        t_end = loop.time() + 20.0  # a starved simulator makes its 1 MB backlog slower
        while len(lags) < 75 or not sink.chunks_dropped:  # 1.5 s at least without reading; nor the pty
            assert loop.time() < t_end, f"no chunk dropped within 20 s ({len(lags)} ticks)"
            t = loop.time()
            await asyncio.sleep(0.02)
            lags.append(loop.time() - t - 0.02)
        # a loop blocked on the full socket would hang here (nobody reads), one held by the slow
        # reader would lag by the seconds it did not read; a starved simulator catching up on its
        # 50x time lags the loop too: up to 0.56 s measured at a load of 21 on 2 cores
        assert max(lags) < 1.0, sorted(lags)[-5:]
        data = bytearray()
        t_read, t_end = loop.time() + 1.5, loop.time() + 20.0
        while loop.time() < t_read or len(data) < DEFAULT_BACKLOG + (512 << 10):  # the backlog, the hole, fresh
            assert loop.time() < t_end, f"{len(data)} bytes read within 20 s"
            data += await reader.read(1 << 16)
        writer.close()
    frames, bad, _ = parse(bytes(data))
    assert bad == 0 and len(seq_gaps(frames)) >= 1  # chunks were dropped ...
    for a, b in zip(frames, frames[1:]):  # ... as whole frames: the byte stream stays framed
        assert b.offset == a.offset + 20 + 2 * a.n_slots * a.n_ch


async def test_board_fifo_overflow_is_flagged():
    """More slots per tick than the board's FIFO holds: frames are lost, the
    next frame says OVERRUN, the revolutions in between stay intact."""
    async with SimRig(SimConfig(), speedup=20.0, can_channel=None, max_slots_per_tick=1500) as rig:
        rig.local_control(spin=150.0, orbit=2 * math.pi * 40)  # ~2900 slots per 10 ms tick
        data = await read_tcp(rig.adc_server.port, min_revs=20)
    frames, bad, _ = parse(data)
    assert bad == 0
    gaps = [(a, b) for a, b in zip(frames, frames[1:]) if b.seq != (a.seq + 1) & 0xFFFF]
    assert gaps and all(b.flags & 0x02 for _, b in gaps)
    assert len(revolutions(frames)) >= 20


async def _refused(port: int) -> bool:
    try:
        _, writer = await asyncio.open_connection("127.0.0.1", port)
    except ConnectionRefusedError:
        return True
    writer.close()
    return False


async def test_a_board_gone_refuses_connections_then_comes_back(rig):
    reader, writer = await asyncio.open_connection("127.0.0.1", rig.adc_server.port)
    assert await reader.read(100)
    rig.inject("adc_board_gone", back_after=0.6)
    t0 = time.monotonic()
    while await asyncio.wait_for(reader.read(1 << 16), 2.0):  # its client dropped
        assert time.monotonic() - t0 < 2.0
    writer.close()
    assert await _refused(rig.adc_server.port)
    assert rig.adc_pty_path is None
    await asyncio.sleep(0.3)
    assert await _refused(rig.adc_server.port) and rig.adc_pty_path is None  # still gone at 0.3 s
    while await _refused(rig.adc_server.port):  # back after 0.6 s: within 3 s with both cores busy
        assert time.monotonic() - t0 < 3.0, "the board did not come back"
        await asyncio.sleep(0.05)
    assert time.monotonic() - t0 > 0.6 - 0.05  # not before its time
    frames, bad, _ = parse(await read_tcp(rig.adc_server.port, min_revs=2))  # back on the same port
    assert bad == 0 and len(revolutions(frames)) >= 2
    assert rig.adc_pty_path is not None


async def test_a_board_gone_for_good_comes_back_on_clear(rig):
    rig.inject("adc_board_gone")
    await asyncio.sleep(1.2)
    assert await _refused(rig.adc_server.port)
    rig.inject("clear")
    await asyncio.sleep(0.1)
    frames, bad, _ = parse(await read_tcp(rig.adc_server.port, min_revs=2))
    assert bad == 0 and len(revolutions(frames)) >= 2
