"""The reconnecting MQTT connection shared by the rig service and the dashboard.

`reconnecting(session, backoff)` runs one connection after another: ``session()`` is
one connection until it is lost (it returns True if the connection carried traffic,
which resets the delays); between two attempts it waits the next jittered, growing
delay of ``backoff`` (daq.backoff: uniform in [d/2, d], d doubling up to its maximum),
so that clients that lost the broker together do not come back in step.
`credentials_refused` tells a refused user name or password from a broker that is away.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Awaitable, Callable

from daq.backoff import Backoff

#: a connection that stayed up this long (s) after subscribing carried traffic: it resets the backoff
TRAFFIC_S = 5.0

#: CONNACK reason codes meaning "your credentials are refused" (MQTT 3.1.1 and 5).
AUTH_REFUSED = frozenset({4, 5, 134, 135})


def return_code(err: BaseException) -> int | None:
    """The CONNACK / reason code an aiomqtt error carries (None if it has none)."""
    rc = getattr(err, "rc", None)
    return getattr(rc, "value", rc)


def credentials_refused(err: BaseException) -> bool:
    """The broker refused the user name or password (not: unreachable, link lost)."""
    import aiomqtt

    return isinstance(err, aiomqtt.MqttCodeError) and return_code(err) in AUTH_REFUSED


async def reconnecting(
    session: Callable[[], Awaitable[bool]],
    backoff: Backoff,
    log: logging.Logger,
    *,
    stop: Callable[[], bool] = lambda: False,
) -> None:
    """``session()`` again and again until ``stop()`` or cancellation; an exception of
    ``session`` ends the loop (a refusal the caller cannot recover from)."""
    while not stop():
        if await session():
            backoff.reset()
        if stop():
            return
        delay = backoff.next_delay()
        log.info("reconnecting in %.2f s", delay)
        await asyncio.sleep(delay)
