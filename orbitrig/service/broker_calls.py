"""aiomqtt's waits for the broker, made to give up a cancellation (the service's and the dashboard's).

aiomqtt 2.5 waits for a CONNACK, SUBACK, UNSUBACK, PUBACK and the end of a DISCONNECT with
``asyncio.wait_for(..., timeout=client.timeout)``; on Python 3.11 a cancel arriving in the loop
turn the broker's answer is read in is taken by that wait and dropped: the call returns as if
none came (a shutdown's cancel lost, the connection read on until the link drops). Here aiomqtt
waits without a bound (``math.inf``: a plain await, which raises the cancel) and
``asyncio.timeout`` bounds the wait instead, by the client's ``timeout`` (s) unless one is given;
running out of it raises ``aiomqtt.MqttError`` ("Operation timed out") as aiomqtt's own did, so
what the callers catch and how they reconnect is unchanged. A connect given up (out of time,
cancelled) closes the connection it may have opened, now or at a later CONNACK: none is left
behind, pinged, on the session's client id.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
from collections.abc import AsyncIterator
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import aiomqtt

#: what running out of the time for the broker's answer raises (aiomqtt's own words)
TIMED_OUT = "Operation timed out"


def paho_of(client: aiomqtt.Client) -> Any:
    """aiomqtt ``client``'s paho client, for what aiomqtt does not offer (its socket, its callbacks,
    its packet reads): aiomqtt 2.5 keeps it as ``_client`` with no public handle; this is the one
    reach into it."""
    return client._client


@contextlib.asynccontextmanager
async def _bounded(seconds: float) -> AsyncIterator[None]:
    """``seconds`` s for the body (``math.inf``: no bound); past them ``aiomqtt.MqttError``."""
    import aiomqtt

    try:
        async with asyncio.timeout(None if seconds == math.inf else seconds):
            yield
    except TimeoutError:
        raise aiomqtt.MqttError(TIMED_OUT) from None


@contextlib.asynccontextmanager
async def _unbounded(client: aiomqtt.Client) -> AsyncIterator[float]:
    """aiomqtt's own waits of ``client`` without a bound while in the body; gives its ``timeout`` (s)."""
    seconds = client.timeout
    client.timeout = math.inf
    try:
        yield seconds
    finally:
        client.timeout = seconds


@contextlib.asynccontextmanager
async def connected(client: aiomqtt.Client) -> AsyncIterator[Any]:
    """``async with client`` (connect, then disconnect), each end's wait for the broker bounded
    by the client's ``timeout`` (s) here and not by aiomqtt (a DISCONNECT's end included). The
    body's exception is what goes on (a disconnection that fails after it is not said)."""
    try:
        async with _unbounded(client) as seconds, _bounded(seconds):
            await client.__aenter__()
    except BaseException:
        _let_go(client)
        raise
    try:
        yield client
    except BaseException:
        import aiomqtt

        with contextlib.suppress(aiomqtt.MqttError):
            await _disconnect(client)
        raise
    await _disconnect(client)


def _let_go(client: aiomqtt.Client) -> None:
    """A connect given up (out of time, cancelled, refused): its socket, if paho opened one, is sent a
    DISCONNECT and closed, and a CONNACK read later does the same, so no connection left behind on the
    session's client id is kept alive (pinged) to take the session over from the next one."""
    paho = paho_of(client)
    paho.on_connect = lambda paho_client, *_: paho_client.disconnect()
    paho.on_disconnect = None  # (aiomqtt's reads its wait for the CONNACK, which a cancel has cancelled)
    paho.disconnect()


async def _disconnect(client: aiomqtt.Client) -> None:
    async with _unbounded(client) as seconds, _bounded(seconds):
        await client.__aexit__(None, None, None)


async def subscribe(
    client: aiomqtt.Client, topic: Any, qos: int = 0, *, timeout: float | None = None, properties: Any = None
) -> Any:
    """``client.subscribe(topic, qos)`` (its SUBACK's reason codes) within ``timeout`` s (None: the client's);
    ``properties``: MQTT 5 SUBSCRIBE properties (a subscription identifier: orbitrig.dashboard.catchup.Via)."""
    async with _bounded(client.timeout if timeout is None else timeout):
        return await client.subscribe(topic, qos, properties=properties, timeout=math.inf)


async def unsubscribe(client: aiomqtt.Client, topic: str | list[str], *, timeout: float | None = None) -> None:
    """``client.unsubscribe(topic)`` within ``timeout`` s (None: the client's)."""
    async with _bounded(client.timeout if timeout is None else timeout):
        await client.unsubscribe(topic, timeout=math.inf)


async def publish(
    client: aiomqtt.Client,
    topic: str,
    payload: Any,
    *,
    qos: int = 0,
    retain: bool = False,
    timeout: float | None = None,
) -> None:
    """``client.publish(...)``, acknowledged (QoS 1) or written (QoS 0) within ``timeout`` s (None: the client's)."""
    async with _bounded(client.timeout if timeout is None else timeout):
        await client.publish(topic, payload, qos=qos, retain=retain, timeout=math.inf)
