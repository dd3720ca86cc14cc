"""The reconnecting MQTT connection shared by the rig service and the dashboard.

`reconnecting(session, backoff)` runs one connection after another: ``session()`` is
one connection until it is lost (it returns True if the connection carried traffic,
which resets the delays); between two attempts it waits the next jittered, growing
delay of ``backoff`` (daq.backoff: uniform in [d/2, d], d doubling up to its maximum),
so that clients that lost the broker together do not come back in step.
`credentials_refused` tells a refused user name or password from a broker that is away;
`refusals` and `watch_publish_refusals` find what the broker refused of a connection (MQTT 5
reason codes >= 0x80 in a SUBACK or a PUBACK: mostly its ACL), and :class:`Delivery` keeps
that and a connection's end-to-end check. What goes on across connections:
:class:`Redeliveries` recognises the broker's redeliveries of messages taken in before, and
`next_message` loses no message when the wait for it is cancelled.
"""

from __future__ import annotations

import asyncio
import collections
import logging
from collections.abc import Awaitable, Callable
from typing import TYPE_CHECKING, Any

from daq.backoff import Backoff
from orbitrig.service import broker_calls
from drives.waits import first_set

if TYPE_CHECKING:
    from orbitrig.service import protocol as proto

#: a connection that stayed up this long (s) after subscribing carried traffic: it resets the backoff
TRAFFIC_S = 5.0

#: CONNACK reason codes meaning "your credentials are refused" (MQTT 3.1.1 and 5).
AUTH_REFUSED = frozenset({4, 5, 134, 135})


def return_code(err: BaseException) -> int | None:
    """The CONNACK / reason code an aiomqtt error carries (None if it has none)."""
    rc = getattr(err, "rc", None)
    return getattr(rc, "value", rc)


def first_error(group: BaseExceptionGroup) -> BaseException:
    """The first exception in ``group``, however deeply nested (task groups in task groups)."""
    err: BaseException = group
    while isinstance(err, BaseExceptionGroup):
        err = err.exceptions[0]
    return err


def seen_as(client: Any, username: str | None, client_id: str) -> str:
    """How the broker's log names the connection of aiomqtt ``client``: the address it comes from
    (the broker logs ``New client connected from <address> as <id>``) and the client id the broker
    gives it: the account ``username`` on a listener that binds ids to accounts
    (``use_username_as_clientid``, the shipped config's service listener; its ACL's ``user``), else
    the id asked for, ``client_id``."""
    try:
        host, port = broker_calls.paho_of(client).socket().getsockname()[:2]
        where = f"{host}:{port}"
    except (AttributeError, OSError, TypeError, ValueError):
        where = "an address not known"
    if username is None:
        return f"from {where}, client id {client_id!r} (the broker's log: New client connected from {where} as {client_id})"
    return (
        f"from {where} as {username!r} (the broker's log: New client connected from {where} as {username}, "
        f"or as the client id asked for, {client_id}, where the listener does not bind ids to accounts)"
    )


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


#: MQTT 5 reason codes from here on say the broker did not do what was asked (e.g. 135: not authorised)
REFUSAL = 0x80


def refusal(code: Any) -> int | None:
    """An MQTT 5 reason code (paho's ReasonCode or an int) if it is a refusal (>= 0x80), else None."""
    value = getattr(code, "value", code)
    return value if isinstance(value, int) and value >= REFUSAL else None


def refusals(codes: Any) -> list[int | None]:
    """Per entry of a SUBACK (aiomqtt's ``subscribe()`` result): :func:`refusal` of its reason code."""
    return [refusal(code) for code in (codes or ())]


def watch_publish_refusals(paho_client: Any, refused: Callable[[str, str], None]) -> None:
    """Have ``refused(topic, reason)`` called for each PUBACK of ``paho_client`` whose reason code
    is a refusal (MQTT 5: the broker acknowledged the message and dropped it, e.g. 135, its ACL
    does not let the account publish there); aiomqtt's ``publish()`` returns as for any other."""
    acknowledged = paho_client.on_publish

    def on_publish(client: Any, userdata: Any, mid: int, reason_code: Any, properties: Any) -> None:
        code = refusal(reason_code)
        if code is not None:
            message = client._out_messages.get(mid)  # (paho forgets it after this callback)
            topic = message.topic if message is not None else "?"
            refused(topic, f"reason code {code}: {reason_code}")
        acknowledged(client, userdata, mid, reason_code, properties)

    paho_client.on_publish = on_publish


class Delivery:
    """What one connection knows of the broker's delivery to it (reset at each connection):
    ``verified``, its end-to-end check came through (``probe``, the status it published
    first, came back: ``echo``); ``problems``, what the broker refused or did not deliver
    (topic -> why), each logged once per connection as an error naming the account and the
    ACL line it needs."""

    def __init__(self, log: logging.Logger, where: str, account: str | None, topics: proto.Topics):
        self.log, self.where, self.account, self.topics = log, where, account, topics
        self.verified = False
        self.problems: dict[str, str] = {}
        self.probe: bytes | None = None
        self.echoed = asyncio.Event()

    def reset(self) -> None:
        self.verified, self.probe = False, None
        self.problems.clear()
        self.echoed.clear()

    @property
    def problem(self) -> str | None:
        """What is known to fail, or None."""
        return "; ".join(self.problems.values()) or None

    def echo(self, payload: bytes) -> None:
        """A message on ``<prefix>/status`` read by this connection."""
        if self.probe is None or payload != self.probe:
            return
        self.echoed.set()
        if self.problems.pop("delivery", None) is not None:  # (a broker slower than the check)
            self.verified = True
            self.log.warning("broker %s, account %r: its own status came back after all", self.where, self.account)

    async def subscribe(self, client: Any, subscriptions: list[tuple[str, int]]) -> None:
        """Subscribe ``client`` (aiomqtt) to ``subscriptions`` and to ``<prefix>/status`` for the
        end-to-end check (no retained copy: only what this connection publishes counts); a
        subscription the broker refuses (MQTT 5 SUBACK) is logged (``refused_on``)."""
        from paho.mqtt.subscribeoptions import SubscribeOptions

        echo = SubscribeOptions(qos=1, retainHandling=SubscribeOptions.RETAIN_DO_NOT_SEND)
        topics: list[tuple[str, Any]] = [*subscriptions, (self.topics.status, echo)]
        for (topic, _), code in zip(topics, refusals(await broker_calls.subscribe(client, topics))):
            if code is not None:
                self.refused_on(topic, f"(reason code {code}) the subscription to")

    async def verify(self, client: Any, seconds: float) -> None:
        """The end-to-end check: ``probe`` must come back within ``seconds`` (then the
        subscription of ``subscribe`` to ``<prefix>/status`` ends). A broker grants a
        subscription its ACL denies, then delivers nothing: without the echo the connection is
        most likely deaf to its commands too."""
        import aiomqtt

        await self._check(seconds)
        try:
            await broker_calls.unsubscribe(client, self.topics.status)
        except aiomqtt.MqttError as err:  # the link is lost: the connection's other tasks see it
            self.log.debug("could not unsubscribe the end-to-end check: %s", err)

    async def _check(self, seconds: float) -> None:
        t = self.topics
        if await first_set(self.echoed, timeout=seconds) is not None:
            self.verified = True
            self.log.info("the broker delivers to %r: its own status came back on %s", self.account, t.status)
        else:
            why = (
                f"the service's own status did not come back on {t.status} within {seconds:g} s: the broker "
                f"delivers nothing to it, most likely no command on {t.cmd} or {t.abort} either (a broker "
                "grants a subscription its ACL denies, then delivers nothing)"
            )
            grant = f"`topic read {t.cmd}`, `topic read {t.abort}`, `topic readwrite {t.status}`, `topic write` "
            grant += f"{t.progress}, {t.result}, {t.live}, {t.reply} and {t.note} (the shipped ACL: orbitrig/+/...)"
            self.refused("delivery", why, grant)

    def refused_on(self, topic: str, what: str) -> None:
        """The broker refused ``what`` (e.g. "(reason code 135) a message on") ``topic`` of the rig's."""
        access = "read" if topic in (self.topics.cmd, self.topics.abort) else "write"
        grant = f"`topic {'readwrite' if topic == self.topics.status else access} {topic}`"
        self.refused(topic, f"it refused {what} {topic}", grant)

    def refused(self, topic: str, why: str, grant: str) -> None:
        """``why`` (the broker refused or did not deliver something on ``topic``): an error naming
        the ACL lines ``grant`` (e.g. ```topic read orbitrig/rig1/cmd```) the account needs."""
        if topic in self.problems:
            return
        self.problems[topic] = why
        self.log.error(
            "broker %s, account %r: %s; its ACL must grant the account, under `user %s`: %s (config/mosquitto/acl)",
            self.where,
            self.account,
            why,
            self.account,
            grant,
        )


class Redeliveries:
    """The broker's redeliveries to a persistent session (MQTT: DUP set, the packet id of the
    first delivery) of QoS 1 messages the client took in, and so acknowledged, on an earlier
    connection (the acknowledgement was lost with the link). ``watch`` each connection's
    paho client; ``redelivered`` says it of each message as it is read."""

    def __init__(self, keep: int = 1024):
        self.keep = keep
        self.connection = 0  # the current connection's number (watch)
        self._dup = False  # the DUP flag of the message being read
        #: (packet id, bytes) of the QoS 1 messages taken in -> the number of their connection
        self._taken: collections.OrderedDict[tuple[int, bytes], int] = collections.OrderedDict()

    def watch(self, paho_client: Any) -> None:
        """A new connection: note the DUP flag of each message it reads (paho's, which
        aiomqtt's messages leave out)."""
        self.connection += 1
        deliver = paho_client.on_message

        def on_message(client: Any, userdata: Any, message: Any) -> None:
            self._dup = bool(message.dup)
            deliver(client, userdata, message)

        paho_client.on_message = on_message

    def redelivered(self, message: Any, payload: bytes) -> bool:
        """True for the redelivery of a QoS 1 message taken in on an earlier connection (DUP
        set, the same packet id and bytes); the message is remembered otherwise. Another
        publication of the same bytes is a new message (DUP clear, another packet id)."""
        if not message.qos:
            return False
        key = (int(message.mid), payload)
        earlier = self._taken.get(key)
        if self._dup and earlier is not None and earlier < self.connection:
            return True
        self._taken[key] = self.connection
        self._taken.move_to_end(key)
        if len(self._taken) > self.keep:
            self._taken.popitem(last=False)
        return False


async def next_message(client: Any, keep: Callable[[Any], None]) -> Any:
    """``client``'s next message (aiomqtt: MqttError once the link is lost). Cancelled, the wait
    goes on, and a message it takes after all is given to ``keep`` (none is lost in between)."""
    task = asyncio.ensure_future(anext(client.messages))
    try:
        return await asyncio.shield(task)
    except asyncio.CancelledError:

        def taken(done: asyncio.Future[Any]) -> None:
            if not done.cancelled() and done.exception() is None:
                keep(done.result())

        task.add_done_callback(taken)
        raise
