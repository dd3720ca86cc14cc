"""Reconnect backoff of the A/D reader against real loopback TCP servers: a peer that
accepts and closes at once is not hammered; the delays start short again only
after good frames flowed."""

from __future__ import annotations

import asyncio
import random

import numpy as np
import pytest
from support.daq_encoder import signal, stream

from daq.adc import AdcReader
from daq.backoff import Backoff

pytestmark = pytest.mark.timeout(30)
WINDOW = 2.0  # s


def test_backoff_grows_with_jitter_and_resets():
    b = Backoff(initial=0.05, maximum=0.5, rng=random.Random(1))
    ceilings, delays = [], []
    for _ in range(8):
        ceilings.append(b.ceiling())
        delays.append(b.next_delay())
    assert ceilings == pytest.approx([0.05, 0.1, 0.2, 0.4, 0.5, 0.5, 0.5, 0.5])
    assert all(c / 2 <= d <= c for c, d in zip(ceilings, delays))
    assert len(set(delays)) == 8  # jittered: no two attempts in lockstep
    b.reset()
    assert b.ceiling() == 0.05 and b.attempts == 0
    with pytest.raises(ValueError):
        Backoff(initial=0.0)
    with pytest.raises(ValueError):
        Backoff(initial=1.0, maximum=float("inf"))


async def serve(payload: bytes):
    """A loopback server sending ``payload`` to each connection, then closing it.
    Returns (server, url, accept times)."""
    loop = asyncio.get_running_loop()
    accepts: list[float] = []

    async def handle(reader, writer):
        accepts.append(loop.time())
        if payload:
            writer.write(payload)
            await writer.drain()
        writer.close()

    server = await asyncio.start_server(handle, "127.0.0.1", 0)
    port = server.sockets[0].getsockname()[1]
    return server, f"socket://127.0.0.1:{port}", accepts


def good_frames() -> bytes:
    frames, _ = stream(signal(2, 8, "sequential", noise=10), "sequential")
    return b"".join(frames)


@pytest.mark.parametrize(
    "payload",
    [b"", np.random.default_rng(0).integers(0, 256, 3000, np.uint8).tobytes()],
    ids=["accept-close", "garbage-close"],
)
async def test_a_peer_that_closes_at_once_is_not_hammered(payload):
    server, url, accepts = await serve(payload)
    async with server:
        reader = AdcReader(url, max_backoff=0.5)
        async with reader:
            await asyncio.sleep(WINDOW)
        attempts = reader.reconnects
    # without backoff this was thousands of connections; with it: 0.05, 0.1, 0.2, 0.4,
    # then 0.5 s ceilings, each delay at least half its ceiling
    assert 4 <= len(accepts) <= 12 and attempts <= 12
    gaps = np.diff(accepts)
    # the first delay at most 0.05 s, below the least of the 0.5 s ceiling's (0.25 s) even with a
    # loaded machine's 0.1-0.2 s late connect (0.14 s seen where 0.12 s was asked)
    assert gaps[0] < 0.25 and gaps[-1] > 0.2 and gaps[-1] > 2 * gaps[0]
    assert len(accepts) - 1 <= reader.link_drops <= len(accepts)


async def test_delays_start_short_again_after_data_flowed():
    server, url, accepts = await serve(good_frames())
    async with server:
        reader = AdcReader(url, max_backoff=0.5)
        async with reader:
            await asyncio.sleep(WINDOW)
    # every connection delivered good frames: every reconnect waits at most the first ceiling
    # (one gap may be longer: a busy machine can stall the test's loop once; a backoff that
    # grew would make every later gap long)
    gaps = np.sort(np.diff(accepts))
    assert len(accepts) >= 15 and gaps[-2] < 0.2, gaps[-3:]
    assert reader.stats.frames_good >= 8 * len(accepts) - 8


async def test_a_reconnect_cancelled_as_its_connect_ends_is_cancelled(monkeypatch):
    """Closing the reader cancels its reconnect task; a cancel that lands in the loop step in
    which the task's connect ends must still end it (Python 3.11's asyncio.wait_for returned
    the connection and dropped the cancel: the task went on and kept a link the reader had
    closed). The alignment in one loop step is forced; the server and sockets are real."""
    server, url, accepts = await serve(b"")  # accepts and closes: the reader keeps reconnecting
    loop = asyncio.get_running_loop()
    reader = AdcReader(url, channels=8, backoff=Backoff(initial=0.02, maximum=0.05))
    try:
        await reader.open()
        while reader._reconnect_task is None:
            await asyncio.sleep(0.01)
        task = reader._reconnect_task
        connect = loop.sock_connect

        async def connect_then_close(sock, addr):
            await connect(sock, addr)
            reader._closed = True  # what aclose does first, in this very step
            task.cancel()

        monkeypatch.setattr(loop, "sock_connect", connect_then_close)
        await asyncio.wait([task], timeout=5.0)
        assert task.done() and task.cancelled(), "the cancel was dropped: the reconnect went on"
    finally:
        monkeypatch.undo()
        await reader.aclose()
        server.close()
        await server.wait_closed()


async def test_a_cancel_of_close_reaches_its_caller_and_the_link_is_closed():
    """A run's cleanup cancelled while the reader closes (waiting for its reconnect task to end):
    the cancel is the caller's and goes on to it, and the reader is closed all the same."""
    server, url, _ = await serve(b"")
    reader = AdcReader(url, channels=8, backoff=Backoff(initial=0.5, maximum=0.5))
    try:
        await reader.open()
        while reader._reconnect_task is None:
            await asyncio.sleep(0.01)
        closing = asyncio.create_task(reader.aclose())
        await asyncio.sleep(0)  # aclose has cancelled the reconnect task and waits for it
        closing.cancel()
        await asyncio.wait([closing], timeout=5.0)
        assert closing.cancelled(), "the caller's cancel was swallowed by the close"
        assert not reader.connected and reader._reconnect_task is None
    finally:
        await reader.aclose()
        server.close()
        await server.wait_closed()
