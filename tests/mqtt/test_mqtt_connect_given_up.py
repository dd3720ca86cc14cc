"""A connect given up (no CONNACK within the client's timeout, or the session cancelled while it
waits) against a broker that reads the CONNECT and answers late: the connection is closed, and a
CONNACK that comes after the give-up does not bring it back to life (a connection left open and
pinged on the session's client id would take the session over from the next one)."""

from __future__ import annotations

import asyncio
import contextlib

import aiomqtt
import pytest

from orbitrig.service import broker_calls

CONNACK = bytes([0x20, 0x03, 0x00, 0x00, 0x00])  # MQTT 5 CONNACK: accepted, no properties


async def _late_broker(answer_after: float) -> tuple[asyncio.Server, asyncio.Future[float]]:
    """A listener that reads the CONNECT, answers it ``answer_after`` s later, and reads on; the
    future gives the s from the accept to the client's closing of the connection."""
    loop = asyncio.get_running_loop()
    closed: asyncio.Future[float] = loop.create_future()

    async def serve(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        t0 = loop.time()
        await reader.read(1024)  # the CONNECT
        await asyncio.sleep(answer_after)
        with contextlib.suppress(ConnectionError):
            writer.write(CONNACK)
            await writer.drain()
            while await reader.read(1024):
                pass
        if not closed.done():
            closed.set_result(loop.time() - t0)
        writer.close()

    return await asyncio.start_server(serve, "127.0.0.1", 0), closed


def _client(server: asyncio.Server, timeout: float) -> aiomqtt.Client:
    port = server.sockets[0].getsockname()[1]
    return aiomqtt.Client(
        "127.0.0.1", port, identifier="given-up", protocol=aiomqtt.ProtocolVersion.V5, timeout=timeout, keepalive=60
    )


async def test_a_connect_out_of_time_closes_its_connection_and_a_late_connack_leaves_it_closed():
    server, closed = await _late_broker(answer_after=0.6)
    async with server:
        client = _client(server, timeout=0.3)
        with pytest.raises(aiomqtt.MqttError, match=broker_calls.TIMED_OUT):
            async with broker_calls.connected(client):
                pytest.fail("connected without a CONNACK")
        assert client.timeout == 0.3  # the client's own bound is back
        took = await asyncio.wait_for(closed, 2.5)  # (before: kept open, pinged, past the test)
        assert took < 1.5


async def test_a_connect_cancelled_while_it_waits_closes_its_connection():
    server, closed = await _late_broker(answer_after=0.5)
    async with server:
        client = _client(server, timeout=5.0)

        async def connect() -> None:
            async with broker_calls.connected(client):
                await asyncio.sleep(10.0)

        task = asyncio.ensure_future(connect())
        await asyncio.sleep(0.2)
        task.cancel()
        with pytest.raises(asyncio.CancelledError):
            await task
        assert client.timeout == 5.0
        took = await asyncio.wait_for(closed, 2.5)
        assert took < 1.5
