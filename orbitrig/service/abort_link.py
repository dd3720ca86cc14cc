"""The rig service's second broker connection, for ``<prefix>/abort`` alone.

A broker delivers one connection's messages in order: on the service's main
connection an abort waits in the socket behind every command of a flood read
before it. This connection reads nothing but ``<prefix>/abort`` (QoS 0
subscription, clean session, no last will, an account of its own:
:class:`orbitrig.service.settings.AbortAccount`), so no flood is ahead of an
abort on it. Each message is handed to the triage's stop/abort fast path as it
is read off the socket (``CommandTriage.urgent``), on the service's event loop;
replies and statuses go out on the main connection.

The main connection keeps its own subscription to ``<prefix>/abort``: an abort
reaches the service on both, and the second copy is dropped (``AbortCopies``).
Without this connection (not configured, its account refused by the broker, or
denied ``<prefix>/abort`` by the ACL) the service still takes every abort, on
the main connection, and says so with a warning when it starts. A broker may
grant the subscription and still deliver nothing (mosquitto, when the ACL denies
the account reading ``<prefix>/abort``); nothing the connection may do shows it
at once (it may publish nothing), so the copies are watched (:class:`WatchedCopies`):
an abort the main connection read while this one was up and that does not come
on this one within ``MISSING_S`` is an error naming the ACL line, and the link is
no longer ``up`` (``delivery.problem`` says why) until a copy comes on it again.
"""

from __future__ import annotations

import asyncio
import dataclasses
import functools
import logging
import time
from typing import Any, cast

from daq.backoff import Backoff
from orbitrig.service import protocol as proto
from orbitrig.service import broker_calls
from orbitrig.service.abort_copies import AbortCopies, Connection
from orbitrig.service.inbox import CommandInbox, CommandTriage
from orbitrig.service.reconnect import TRAFFIC_S, Delivery, credentials_refused, reconnecting, refusals, seen_as
from orbitrig.service.settings import AbortAccount, BrokerSettings, ServiceError, ServiceSettings

log = logging.getLogger("orbitrig.service.abort_link")

#: s within which a message on <prefix>/abort the main connection read must come on the abort connection
MISSING_S = 5.0


class AbortConnectionRefused(ServiceError):
    """The broker refused the abort connection's account or its subscription (the
    service goes on without it)."""


@dataclasses.dataclass
class AbortLink:
    """The abort connection of one rig service: ``await run()`` until cancelled.
    ``up`` is True while it is subscribed and not known to be denied its messages
    (``delivery.problem`` then says why); ``refused`` says why it gave up."""

    broker: BrokerSettings
    account: AbortAccount
    settings: ServiceSettings
    topics: proto.Topics
    triage: CommandTriage
    up: bool = False
    connections: int = 0
    refused: str | None = None
    subscribed: bool = False

    def __post_init__(self) -> None:
        self.delivery = Delivery(log, self.where, self.account.username, self.topics)
        self.triage.copies = cast(AbortCopies, WatchedCopies(self, self.triage.copies))  # (duck-typed)

    def delivered(self) -> None:
        """A message on ``<prefix>/abort`` came on this connection: it delivers."""
        self.delivery.verified = True
        if self.delivery.problems.pop(self.topics.abort, None) is not None:
            log.warning("abort connection: the broker delivers %s to it again", self.topics.abort)
        self.up = self.subscribed

    def missed(self) -> None:
        """A message on ``<prefix>/abort`` the main connection read did not come on this one (MISSING_S)."""
        topic = self.topics.abort
        why = (
            f"a message on {topic} the main connection read did not come on the abort connection within "
            f"{MISSING_S:g} s: the broker granted its subscription and delivers nothing (its ACL); stop and "
            "abort are taken on the main connection only, where a flood of commands can hold them back"
        )
        self.delivery.verified = False
        self.delivery.refused(topic, why, f"`topic read {topic}` (the shipped ACL: `topic read orbitrig/+/abort`)")
        self.up = False

    @property
    def where(self) -> str:
        return f"{self.broker.host}:{self.broker.port}"

    async def run(self) -> None:
        """Connect and reconnect (jittered backoff) until cancelled; on a refusal, warn and end."""
        try:
            backoff = Backoff(self.settings.reconnect_initial, self.settings.reconnect_max)
            await reconnecting(self._session, backoff, log)
        except AbortConnectionRefused as err:
            self.refused = str(err)
            log.warning(
                "%s: stop and abort are still taken on %s through the main connection, but there they "
                "may wait behind a flood of commands (the broker folder's README.md, `orbitrig init` DIR/mosquitto: "
                "The abort account; its password is the service's unless --abort-password-file gives one)",
                err,
                self.topics.abort,
            )
        except Exception:  # a fault of this connection must not end the service: the main one goes on
            self.refused = "failed"
            log.exception("abort connection failed; stop and abort are still taken on the main connection")

    def _client(self) -> Any:
        import aiomqtt

        b, account = self.broker, self.account
        tls = aiomqtt.TLSParameters(ca_certs=str(b.tls_ca) if b.tls_ca else None) if b.tls else None
        return aiomqtt.Client(
            b.host,
            b.port,
            username=account.username,
            password=account.password,
            identifier=self.settings.abort_client_id,
            protocol=aiomqtt.ProtocolVersion.V5,
            clean_start=True,
            keepalive=b.keepalive,
            timeout=b.timeout,
            tls_params=tls,
            # aiomqtt calls queue_type(maxsize): a factory serves as well as a class
            queue_type=functools.partial(  # type: ignore[arg-type]
                CommandInbox, take_now=self._take, overflow=lambda message: None
            ),
        )

    def _take(self, message: Any) -> bool:
        """Every message as it is read off the socket: to the fast path (``<prefix>/abort`` only)."""
        if str(message.topic) == self.topics.abort:
            payload = message.payload
            data = bytes(payload) if isinstance(payload, (bytes, bytearray)) else str(payload or "").encode()
            self.triage.urgent(data, bool(message.retain), via=Connection.ABORT)
        return True

    async def _session(self) -> bool:
        """One connection until it is lost; True if it carried traffic (up for TRAFFIC_S)."""
        import aiomqtt

        t_up = None
        try:
            async with broker_calls.connected(self._client()) as client:
                granted = await broker_calls.subscribe(client, self.topics.abort, proto.QOS_ABORT_SUBSCRIPTION)
                self._check_granted(granted)
                t_up, self.subscribed = time.monotonic(), True
                self.up = self.delivery.problem is None  # (known to be denied its messages: not up)
                self.connections += 1
                log.info(
                    "abort connection to %s %s: stop and abort on %s",
                    self.where,
                    seen_as(client, self.account.username, self.settings.abort_client_id),
                    self.topics.abort,
                )
                async for _ in client.messages:
                    pass  # every message is taken as it is read (_take); nothing is queued
        except aiomqtt.MqttError as err:
            if credentials_refused(err) and self.connections == 0:
                raise AbortConnectionRefused(
                    f"broker {self.where} refused the abort connection's account {self.account.username!r}: {err}"
                ) from None
            log.warning("abort connection to %s %s: %s", self.where, "lost" if self.subscribed else "failed", err)
        finally:
            self.up = self.subscribed = False
            self.triage.copies.closed(Connection.ABORT)  # it delivers nothing more: its copies are not awaited
        return t_up is not None and time.monotonic() - t_up > TRAFFIC_S

    def _check_granted(self, granted: Any) -> None:
        """A subscription the broker refused (MQTT 5 reason code >= 0x80: the ACL) ends the link."""
        refused = [code for code in refusals(granted) if code is not None]
        if refused:
            raise AbortConnectionRefused(
                f"broker {self.where} refused the abort connection's account {self.account.username!r} "
                f"the subscription to {self.topics.abort} (reason code {refused[0]}: its ACL)"
            )


class WatchedCopies:
    """The triage's own :class:`AbortCopies` (``copies``: they pair the copies; everything but
    ``first`` goes to them), watched for ``link``, the abort connection: a message on
    ``<prefix>/abort`` the main connection reads first while ``link`` is subscribed must be
    followed by a copy on ``link`` within MISSING_S (``missed`` else, on the event loop); every
    copy that comes on ``link`` says it delivers (``delivered``)."""

    def __init__(self, link: AbortLink, copies: AbortCopies):
        self._link, self._copies = link, copies
        self._awaited: list[bytes] = []  # read off the main connection, not yet off the abort one

    def __getattr__(self, name: str) -> Any:
        return getattr(self._copies, name)

    def first(self, via: Connection, payload: bytes, *args: Any, **kwargs: Any) -> bool:
        first = self._copies.first(via, payload, *args, **kwargs)
        if via is Connection.ABORT:  # it delivers: not denied (a copy it missed is no ACL's doing)
            self._awaited.clear()
            self._link.delivered()
        elif first and self._link.subscribed:
            try:
                loop = asyncio.get_running_loop()
            except RuntimeError:  # (not on the event loop: not watched)
                return first
            self._awaited.append(bytes(payload))
            loop.call_later(MISSING_S, self._check, bytes(payload), self._link.connections)
        return first

    def _check(self, payload: bytes, connection: int) -> None:
        if payload in self._awaited:
            self._awaited.remove(payload)
            if self._link.subscribed and self._link.connections == connection:
                self._link.missed()
