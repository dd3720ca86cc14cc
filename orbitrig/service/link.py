"""The rig service's connection to the broker (aiomqtt, MQTT 5).

:class:`BrokerLink` owns one persistent session (clean start off, session
expiry ``ServiceSettings.session_expiry`` s, a stable client id), so QoS 1
commands published while the link is down are kept by the broker and handed
over on reconnection. It reconnects with jittered exponential backoff, reset
only after a connection carried traffic; keeps an ordered outgoing queue (the
current status first after every connection; QoS 0 messages and stale
statuses are not queued while offline); registers ``offline`` as the last
will and publishes it itself when a session ends for any reason but a lost
link (a clean disconnect does not trigger the will), from the moment it is
connected (a shutdown while it subscribes too); one that did not get it to the
broker (a shutdown before its CONNACK, where the will may have gone out) has
``discard_session`` publish it on its clean connection. MQTT fixes the will when
the service connects: its ``run_id`` and ``since`` are of that moment, and its
``last_will`` field says so (a run started later is not in it).

Commands come in through :class:`orbitrig.service.inbox.CommandInbox` (stop
and abort carried out as they are read off the socket, the rest queued and
bounded). The client acknowledges a QoS 1 command as it reads it, so the broker
never sends it again: what a lost connection took in and did not hand over is
carried out on the next one, first. The broker's redelivery of a command whose
acknowledgement was lost with the link (DUP set, the packet id and bytes of one
taken in before) is dropped: each command is carried out and answered once.

Going out, messages wait in two lanes (orbitrig.service.outbox, the link's base):
replies to ordinary commands behind statuses and results, each lane in order.

Every connection checks that the broker delivers to it (mosquitto grants a
subscription its ACL denies, then delivers nothing): its own status, published
first, must come back on ``<prefix>/status`` within ``ECHO_S``; a PUBACK refusing
a message (reason code >= 0x80, e.g. 135: the ACL) is an error. ``delivery``
(``verified``, ``problem``) says how that went (reconnect.Delivery).
"""

from __future__ import annotations

import asyncio
import collections
import functools
import json
import logging
import time
from collections.abc import Callable
from typing import Any

from orbitrig.service import broker_calls
from orbitrig.service import protocol as proto
from daq.backoff import Backoff
from orbitrig.service.flood_read import hold_reading, read_in_bursts, shed_before_decoding
from orbitrig.service.inbox import CommandInbox, CommandTriage
from orbitrig.service.outbox import PUBLISH_WINDOW, Outbox
from orbitrig.service.reconnect import TRAFFIC_S, Delivery, Redeliveries, credentials_refused, first_error
from orbitrig.service.reconnect import next_message, reconnecting, seen_as, watch_publish_refusals
from orbitrig.service.settings import BrokerSettings, ServiceError, ServiceSettings

log = logging.getLogger("orbitrig.service.link")

#: s within which the service's own status must come back to it on every connection
ECHO_S = 10.0
#: where the broker's set-up is told, named while the service has never reached its broker
BROKER_SETUP = "start it as config/mosquitto/README.md says; retrying"
#: the last will's message, and what the will says of itself (its ``last_will`` field)
WILL_MESSAGE = "connection to the rig service lost"
WILL_NOTE = (
    "the broker published this last will, registered when the service connected ({since}): its run_id "
    "and since are of that moment, not of the loss; a run started later is named by the statuses "
    "before this one, and its stored status in the service's runs folder still says running "
    "(orbitrig sweep --resume continues it)"
)


def _drop(message: Any) -> bool:
    return True  # (the connection that only ends the session subscribes to nothing)


class BrokerLink(Outbox):
    """The broker side of one rig service. ``status()`` gives the current status
    payload, ``offline(message)`` an ``offline`` status; ``on_command(payload,
    retained)`` gets each ordinary message on ``<prefix>/cmd`` in turn,
    ``triage`` sees every one as it arrives."""

    def __init__(
        self,
        broker: BrokerSettings,
        settings: ServiceSettings,
        topics: proto.Topics,
        *,
        status: Callable[[], bytes],
        offline: Callable[[str], bytes],
        on_command: Callable[[bytes, bool], None],
        triage: CommandTriage,
    ):
        super().__init__(topics, self._probe_status)
        self.broker, self.settings = broker, settings
        self._status, self._offline, self._on_command = status, offline, on_command
        self.triage = triage
        self._inbox: CommandInbox | None = None  # the current connection's
        #: commands taken out of an inbox (or left in that of a lost connection), not yet handed over
        self._pending: collections.deque[Any] = collections.deque()
        self._redeliveries = Redeliveries()
        #: the current connection's end-to-end check (ECHO_S) and what the broker refused it
        self.delivery = Delivery(log, self.where, broker.username, topics)
        self._paho: Any = None  # the current connection's paho client
        self.offline = asyncio.Event()
        self.offline.set()
        self.leaving = False  # set by the owner once "offline" was queued for a clean exit
        self.said_offline = False  # "offline" reached the broker since the last connection (_leave)
        self._reading = True  # ordinary commands are read (stop_commands: no more)
        self._commands: asyncio.Task | None = None  # the current connection's command loop
        self.connections = 0  # successful connections so far
        self.connected_at = 0.0  # time.monotonic() of the latest connection

    @property
    def where(self) -> str:
        return f"{self.broker.host}:{self.broker.port}"

    def _probe_status(self) -> bytes:
        """The status sent first on a connection: the end-to-end check, it must come back (Delivery.verify)."""
        self.delivery.probe = payload = self._status()
        return payload

    # -- incoming -------------------------------------------------------------------

    async def _command_loop(self, client: Any) -> None:
        """Ordinary commands in turn, as fast as the triage allows (stop and abort never get
        here: ``_take_now``), first those a lost connection took in (acknowledged: not resent)."""
        inbox, pending = self._inbox, self._pending
        while True:
            if not pending:
                if inbox is not None and not inbox.empty():
                    pending.append(inbox.get_nowait())
                else:
                    self.triage.flush_report()
                    pending.append(await next_message(client, keep=pending.appendleft))
            await self.triage.turn()
            message = pending.popleft()  # (nothing is awaited from here on: handed over, or still pending)
            self._on_command(self._payload(message), bool(message.retain))

    def stop_commands(self) -> None:
        """Read no more ordinary commands (the service is shutting down); a stop or an
        abort is still carried out as it arrives (``_take_now``)."""
        self._reading = False
        if self._commands is not None:
            self._commands.cancel()

    def _new_inbox(self, maxsize: int = 0) -> CommandInbox:
        """A new connection's incoming queue (made by the client: ``queue_type``); what the last one
        took in and did not hand over waits for this one (``_pending``)."""
        old = self._inbox
        while old is not None and not old.empty():
            self._pending.append(old.get_nowait())
        if self._pending:
            log.info("%d commands the lost connection took in are carried out on the next one", len(self._pending))
        self.delivery.reset()
        self._inbox = CommandInbox(maxsize, take_now=self._take_now, overflow=self._overflow)
        return self._inbox

    @staticmethod
    def _payload(message: Any) -> bytes:
        payload = message.payload
        return bytes(payload) if isinstance(payload, (bytes, bytearray)) else str(payload or "").encode()

    def _take_now(self, message: Any) -> bool:
        """Each message as it is read off the socket: True if dealt with (stop,
        abort, anything on ``<prefix>/abort``, a topic not subscribed to)."""
        topic = str(message.topic)
        if topic == self.topics.abort:
            self.triage.urgent(self._payload(message), bool(message.retain))
            return True
        if topic == self.topics.status:  # the end-to-end check (Delivery.verify)
            self.delivery.echo(self._payload(message))
            return True
        if topic != self.topics.cmd:
            return True
        payload = self._payload(message)
        return self.triage.at_once(payload, bool(message.retain)) or self._redelivered(message, payload)

    def _redelivered(self, message: Any, payload: bytes) -> bool:
        """The broker's redelivery of a command taken in before the link dropped: dropped."""
        if redelivered := self._redeliveries.redelivered(message, payload):
            log.info(
                "dropped the broker's redelivery of command %r (packet %s): taken in once", payload[:80], message.mid
            )
        return redelivered

    def _shed(self, payload: bytes, retained: bool) -> bool:
        """A message on ``<prefix>/cmd`` before it is decoded: True if answered busy or
        dropped there (the queue is full and it cannot be a stop or an abort)."""
        inbox = self._inbox
        return inbox is not None and inbox.full() and self.triage.shed(payload, retained)

    def _overflow(self, message: Any) -> None:
        self.triage.overflow(self._payload(message), bool(message.retain))

    # -- connection -----------------------------------------------------------------

    def _client(self, *, clean_start: bool = False) -> Any:
        import aiomqtt
        from paho.mqtt.packettypes import PacketTypes
        from paho.mqtt.properties import Properties

        b = self.broker
        will = aiomqtt.Will(self.topics.status, self._will(), qos=proto.QOS_STATUS, retain=True)
        tls = aiomqtt.TLSParameters(ca_certs=str(b.tls_ca) if b.tls_ca else None) if b.tls else None
        session = Properties(PacketTypes.CONNECT)
        session.SessionExpiryInterval = 0 if clean_start else self.settings.session_expiry
        client = aiomqtt.Client(
            b.host,
            b.port,
            username=b.username,
            password=b.password,
            identifier=self.settings.mqtt_client_id,
            will=None if clean_start else will,
            protocol=aiomqtt.ProtocolVersion.V5,
            clean_start=clean_start,
            properties=session,
            keepalive=b.keepalive,
            timeout=b.timeout,
            tls_params=tls,
            max_queued_incoming_messages=self.triage.limit,
            # aiomqtt calls queue_type(maxsize): a factory serves as well as a class
            queue_type=functools.partial(CommandInbox, take_now=_drop, overflow=_drop)  # type: ignore[arg-type]
            if clean_start
            else self._new_inbox,
        )
        client.pending_calls_threshold = PUBLISH_WINDOW + 8  # a full window is expected, not a warning
        paho = broker_calls.paho_of(client)
        read_in_bursts(paho, taken_at_once=lambda: self.triage.counts["at once"])
        shed_before_decoding(paho, self.topics.cmd, self._shed)
        if not clean_start:
            self._paho = paho
            self._redeliveries.watch(paho)  # the DUP flag of each message read (_redelivered)
            watch_publish_refusals(paho, lambda topic, why: self.delivery.refused_on(topic, f"({why}) a message on"))
        return client

    def _will(self) -> bytes:
        """``offline`` as of this connection, with ``last_will`` saying so (fixed at CONNECT)."""
        status = json.loads(self._offline(WILL_MESSAGE))
        status["last_will"] = WILL_NOTE.format(since=status["since"])
        return proto.dumps(status)

    def hold_reading(self, seconds: float, until: asyncio.Future[Any] | None = None) -> bool:
        """Leave the connection unread for ``seconds`` s, or until ``until`` is done (flood_read.hold_reading)."""
        return self._paho is not None and hold_reading(self._paho, seconds, until)

    async def run(self) -> None:
        """Connect, and reconnect after every loss, until cancelled."""
        await reconnecting(self._session, Backoff(self.settings.reconnect_initial, self.settings.reconnect_max), log)

    async def _session(self) -> bool:
        """One connection, until it is lost. True if it carried traffic
        (subscribed, then up for at least TRAFFIC_S)."""
        import aiomqtt

        t_connected, self.said_offline = None, False  # a will is registered from its CONNECT on
        try:
            async with broker_calls.connected(self._client()) as client:
                try:  # connected: the will is registered, the way out says offline (a shutdown while subscribing too)
                    await self.delivery.subscribe(
                        client, [(self.topics.cmd, proto.QOS_CMD), (self.topics.abort, proto.QOS_ABORT_SUBSCRIPTION)]
                    )
                    t_connected = self.connected_at = time.monotonic()
                    self._connected(client)
                    async with asyncio.TaskGroup() as session:
                        session.create_task(self.delivery.verify(client, ECHO_S), name="mqtt-verify")
                        session.create_task(self._publish_loop(client), name="mqtt-publish")
                        if self._reading:
                            self._commands = session.create_task(self._command_loop(client), name="mqtt-commands")
                finally:
                    await self._leave(client)
        except* aiomqtt.MqttError as group:
            self._connection_failed(first_error(group), connected=t_connected is not None)
        finally:
            self.online.clear()
            self.offline.set()
        return t_connected is not None and time.monotonic() - t_connected > TRAFFIC_S

    def _connected(self, client: Any) -> None:
        """Subscribed: counted, said (as the broker's log names it), and ``online`` (the outbox sends)."""
        self.connections += 1
        log.info(
            "connected to %s %s; commands on %s, stop and abort also on %s",
            self.where,
            seen_as(client, self.broker.username, self.settings.mqtt_client_id),
            self.topics.cmd,
            self.topics.abort,
        )
        self.offline.clear()
        self.online.set()

    def _connection_failed(self, err: BaseException, *, connected: bool) -> None:
        if self.connections == 0 and credentials_refused(err):
            raise ServiceError(
                f"broker {self.where} refused the credentials of {self.broker.username!r}: {err}"
            ) from None
        if connected:
            log.warning("connection to %s lost: %s", self.where, err)
        else:  # never connected yet: most often no broker runs there
            hint = "" if self.connections else f" (is a broker running there? {BROKER_SETUP})"
            log.warning("cannot connect to %s: %s%s", self.where, err, hint)

    async def _leave(self, client: Any) -> None:
        """Publish ``offline`` (retained) before the session ends for any reason
        but a lost link (shutdown, a fault in the service)."""
        if self.leaving and self.drained.is_set():
            self.said_offline = True
            return  # the owner's offline status has been delivered
        try:
            await self._say_offline(client)
        except Exception as err:  # noqa: BLE001 - the link may be gone: the last will covers that
            log.debug("could not publish offline on the way out: %s", err)

    async def _say_offline(self, client: Any) -> None:
        """``offline`` ('rig service stopped', retained, no ``last_will``) on `client`, acknowledged within 3 s."""
        offline = self._offline("rig service stopped")
        await broker_calls.publish(client, self.topics.status, offline, qos=proto.QOS_STATUS, retain=True, timeout=3.0)
        self.said_offline = True

    async def discard_session(self) -> None:
        """Make the broker forget the session (after a clean shutdown): commands
        sent while no service runs are not executed by the next one; the
        persistent session bridges reconnections, not restarts. An ``offline`` the last
        session did not get to the broker (a shutdown before its CONNACK: the broker may have
        published the will; or while it subscribed) is published on this connection."""
        try:
            async with asyncio.timeout(5.0):
                async with broker_calls.connected(self._client(clean_start=True)) as client:
                    if not self.said_offline:
                        await self._say_offline(client)
        except Exception as err:  # noqa: BLE001 - the session then expires on its own
            log.info("could not discard the broker session: %s", err)
