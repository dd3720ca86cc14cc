"""One signed-in person of the dashboard: an MQTT connection AS THAT BROKER USER.

The broker authenticates the connection and its ACL decides what the person
may do: the dashboard adds no rights of its own. The password lives only in
this object (server-side memory) for the reconnections; it is never logged.

A :class:`Session` watches one rig of the broker at a time (``select_rig``) and keeps
what the page needs to draw itself at once, fanning every rig message out to the session's
browser feeds (orbitrig.dashboard.incoming). The connection is MQTT 5, so that the broker
answers a publish its ACL refuses with reason code 135 (orbitrig.dashboard.puback). A command is published with a
correlation id and answered by the service's reply; refused by the broker, it is reported
as not authorised; without a reply within ``reply_timeout`` its outcome is unknown
(orbitrig.dashboard.commands).

The broker keeps the session's MQTT session a while after its link drops, so that what was
published meanwhile comes when it is back; else the pages learn that results may be missing
(orbitrig.dashboard.catchup). Sign-out ends the broker's session with the connection.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import dataclasses
import logging
import secrets
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import orbitrig.service.protocol as proto
from daq.backoff import Backoff
from orbitrig.dashboard.alarms import AlarmShelf
from orbitrig.dashboard.catchup import (
    Via,
    connect_properties,
    gap_message,
    keep_subscribing,
    move_subscriptions,
    subscriptions,
    tagged,
    topic_names,
    via_of,
)
from orbitrig.dashboard.commands import PAGE_COMMANDS
from orbitrig.dashboard.elsewhere import ElsewhereReplies
from orbitrig.dashboard.feed import BrokerLink, Feed, FeedType
from orbitrig.dashboard.incoming import Incoming
from orbitrig.dashboard.lifted import PageTypesetting
from orbitrig.dashboard.link_lost import WILL_NEAR_OUTAGE_S, Outage
from orbitrig.dashboard.outgoing import Outgoing
from orbitrig.dashboard.rigs import RigDirectory
from orbitrig.dashboard.defaults import IDLE_TIMEOUT_S, REPLY_TIMEOUT_S, REQUEST_TIMEOUT_S, SESSIONS_PER_USER, TICK_S
from orbitrig.dashboard.throttle import ThrottlePolicy
import orbitrig.service.broker_calls as broker_calls
from orbitrig.service.reconnect import credentials_refused, reconnecting

log = logging.getLogger("orbitrig.dashboard")

__all__ = ["PAGE_COMMANDS", "DashboardSettings", "Session", "SignInRefused"]


class SignInRefused(Exception):
    """The broker refused the person's credentials (`credentials`), or cannot be reached."""

    def __init__(self, message: str, credentials: bool):
        super().__init__(message)
        self.credentials = credentials


@dataclasses.dataclass(frozen=True)
class DashboardSettings:
    """Broker address, topic prefix, the dashboard's times (s) and limits: sessions per broker
    user, sign-in throttling (orbitrig.dashboard.throttle), the read deadline of a request."""

    host: str
    port: int
    topics: proto.Topics
    tls: bool = False
    tls_ca: Path | None = None
    idle_timeout: float = IDLE_TIMEOUT_S
    reply_timeout: float = REPLY_TIMEOUT_S
    tick: float = TICK_S  # s without a message to a page after which a tick goes (defaults.TICK_S: the page's limits)
    keepalive: int = 10
    sessions_per_user: int = SESSIONS_PER_USER
    throttle: ThrottlePolicy = ThrottlePolicy()
    request_timeout: float = REQUEST_TIMEOUT_S
    trend_period: float = 1.0  # s between trend samples
    trend_recent_s: float = 1800.0  # s of recent trend samples kept (the run's own view is thinned instead)
    catch_up_s: int = 600  # s the broker keeps the session's messages while its link is down (session expiry)
    #: how the page names the live feed's channels: channel -> (symbol, subscript, after), given by the
    #: caller from the report's typesetting (orbitrig.analysis.typeset.force_channels); sent in the hello
    names: Mapping[str, tuple[str, str, str]] = dataclasses.field(default_factory=dict)
    #: how the page writes the names and messages it shows typeset (a coefficient's key, K<sub>xx</sub>; a
    #: message's u<sub>x</sub>): the report's rules, given by the caller (orbitrig.analysis.typeset); made by
    #: the server, sent beside the plain text (orbitrig.dashboard.lifted)
    typeset: PageTypesetting = PageTypesetting()


class Session(Incoming, Outgoing):
    """One browser session = one broker user's MQTT connection (what it reads: Incoming; its commands:
    Outgoing; Incoming first, as its `alarms` and `_broadcast` are the ones Outgoing uses)."""

    def __init__(self, settings: DashboardSettings, user: str, password: str, shelf: AlarmShelf | None = None):
        self.settings = settings
        self.shelf = shelf if shelf is not None else AlarmShelf()  # the server's: shared by its sessions
        self.user = user
        self.__password = password
        self.token = secrets.token_urlsafe(32)
        self.last_active = time.monotonic()
        self.link = BrokerLink.CONNECTING
        self.topics = settings.topics  # the rig watched now (select_rig changes it)
        self.rigs = RigDirectory(settings.topics.prefix)
        self._forget_rig()
        self.feeds: set[Feed] = set()
        self._pending: dict[str, asyncio.Future] = {}
        self._late: dict[str, tuple[str, float, str]] = {}
        self._elsewhere = ElsewhereReplies()  # reply topics of rigs not watched, read while a reply is awaited
        self.outcomes = collections.deque(maxlen=10)
        self._client: Any = None
        self._task: asyncio.Task | None = None
        self.closed = False
        self._subscribed: proto.Topics | None = None  # the rig the broker's session holds subscriptions to
        self._resubscribing: asyncio.Task | None = None  # subscribing to a rig chosen, its SUBACK not come
        self._down_since: str | None = None  # when the broker link was lost (ISO-8601), until it is back
        self.outage: Outage | None = None  # the latest broker outage seen (orbitrig.dashboard.link_lost)
        self._grace: asyncio.TimerHandle | None = None  # when an outage's last wills are read offline again

    def __repr__(self) -> str:  # never the password
        return f"Session(user={self.user!r}, link={str(self.link)!r})"

    async def select_rig(self, rig_id: str, peers: Any = ()) -> dict:
        """Watch another rig of the broker (``orbitrig/<rig_id>``) from now on (with the trends
        and alarms of a session of ``peers`` watching it already)."""
        if self.rigs.root is None:
            return {"ok": False, "error": f"this dashboard watches the topic tree {self.topics.prefix} only"}
        try:
            new = proto.topics(rig_id)
        except ValueError as err:
            return {"ok": False, "error": str(err)}
        if new == self.topics:
            return {"ok": True, "prefix": new.prefix}
        old, client = self.topics, self._client
        self.topics = new
        self._forget_rig()
        self._broadcast({"type": FeedType.RIG, "prefix": new.prefix})
        self.adopt(peers)
        log.info("session of %r: now watching %s", self.user, new.prefix)
        self._stop_resubscribing()  # the rig chosen before is not subscribed to any more
        if client is not None:
            self._read_listed(rig_id)  # shown at once, not after the SUBACK (up to the client's timeout if late)
            if await move_subscriptions(client, old, new, self.user, self._elsewhere.awaited()):
                if self.topics == new:  # else another page chose a rig meanwhile: its own move decides
                    self._subscribed = new
            elif self.topics == new and self._client is client:
                self._resubscribe(client, new)
            self._elsewhere.resubscribe(client)  # a reply awaited on the rig left: read on
        return {"ok": True, "prefix": new.prefix}

    def _resubscribe(self, client: Any, topics: proto.Topics) -> None:
        """The broker did not confirm the subscription to the rig chosen (its SUBACK late, or none) while the link
        stays up: try again until it does (catchup.keep_subscribing), the rig's status meanwhile read from the
        rigs' copy (orbitrig.dashboard.incoming). Given up when another rig is chosen, on sign-out, or when the
        link drops (the reconnection subscribes to the rig watched then)."""

        def given_up() -> bool:
            return self.closed or self.topics != topics or self._client is not client

        def attempt() -> None:  # the retained status a confirmed subscription hands on again: not sent twice
            self.status_expected = self.status

        async def subscribing() -> None:
            if await keep_subscribing(client, topics, self.user, given_up, attempt) and not given_up():
                self._subscribed = topics

        self._resubscribing = asyncio.get_running_loop().create_task(subscribing(), name=f"resubscribe-{self.user}")

    def _stop_resubscribing(self) -> asyncio.Task | None:
        """No more attempts to subscribe to a rig chosen: its task cancelled (it ends at its next await)."""
        task, self._resubscribing = self._resubscribing, None
        if task is not None:
            task.cancel()
        return task

    def touch(self) -> None:
        self.last_active = time.monotonic()

    # -- connection --------------------------------------------------------------

    def _make_client(self) -> Any:
        import aiomqtt

        from orbitrig.dashboard.puback import ReasonClient

        s = self.settings
        tls = aiomqtt.TLSParameters(ca_certs=str(s.tls_ca) if s.tls_ca else None) if s.tls else None
        return ReasonClient(  # MQTT 5: a publish the ACL refuses is answered with reason code 135
            s.host,
            s.port,
            username=self.user,
            password=self.__password,
            identifier=f"mosq-orbitrig-dashboard-{self.user}-{self.token[:8]}",  # the same on every reconnection
            protocol=aiomqtt.ProtocolVersion.V5,
            # never a clean start: the id is new at each sign-in (its token), so the first connection
            # gets a fresh session all the same, and mosquitto 2.0 saves to its persistence only the
            # sessions not begun with a clean start (with one, a broker restart lost the session)
            clean_start=False,
            properties=connect_properties(s.catch_up_s),  # the broker keeps the session this long
            keepalive=s.keepalive,
            timeout=10,
            tls_params=tls,
        )

    async def open(self) -> None:
        """Connect as the user; raises SignInRefused (wrong credentials, no broker)."""
        first: asyncio.Future = asyncio.get_running_loop().create_future()
        self._task = asyncio.create_task(self._connection_loop(first), name=f"dashboard-{self.user}")
        await first

    async def _connection_loop(self, first: asyncio.Future) -> None:
        await reconnecting(lambda: self._connection(first), Backoff(0.2, 5.0), log, stop=lambda: self.closed)

    async def _connection(self, first: asyncio.Future) -> bool:
        """One broker connection until it is lost; True if it came up. A refusal at
        sign-in, or of credentials that worked before, ends the session."""
        import aiomqtt

        connected = False
        try:
            async with broker_calls.connected(self._make_client()) as client:
                caught_up = client.session_present and self._subscribed == self.topics
                self._stop_resubscribing()  # the new link's subscriptions are those of the rig watched now
                self.status_expected = None  # its retained status handed on again is read as after any outage
                await self._subscribe(client)
                self._client, connected = client, True
                if not first.done():
                    first.set_result(None)
                self._outage_over()
                self._set_link(BrokerLink.ONLINE)
                self._link_back(caught_up)
                if self.closed:  # signed out while connecting
                    self._end_broker_session()
                async for message in client.messages:
                    self._on_message(str(message.topic), message.payload, via_of(message.properties))
            return True
        except aiomqtt.MqttError as err:
            self._client = None
            if self.closed:  # signed out: the session's own disconnection
                return connected
            if connected:
                self._down_since, self.outage = proto.iso8601(), Outage(time.monotonic())
                self._end_grace()  # the new outage's reading holds until its own link is back
            refused = credentials_refused(err)
            if not first.done():
                first.set_exception(
                    SignInRefused(
                        "refused: wrong user name or password"
                        if refused
                        else f"cannot reach the broker {self.settings.host}:{self.settings.port}",
                        refused,
                    )
                )
                self.closed = True
            elif refused:
                log.warning("broker no longer accepts %r: session ended", self.user)
                self._broadcast({"type": FeedType.SIGNED_OUT, "reason": "the broker refused your credentials"})
                self.closed = True
            else:
                self._set_link(BrokerLink.UNREACHABLE)
                if connected:  # the outage begins: a last will heard just before it came with it
                    self._link_lost_anew()
            return connected

    async def _subscribe(self, client: Any) -> None:
        """Subscribe to the rig watched (and the rigs' statuses), each named (catchup.Via); a resumed session's
        subscriptions to a rig left while the link was down go."""
        old = self._subscribed
        await broker_calls.subscribe(client, subscriptions(self.topics), properties=tagged(Via.WATCHED))
        if self.rigs.pattern is not None:
            await broker_calls.subscribe(client, self.rigs.pattern, 1, properties=tagged(Via.RIGS))
        self._elsewhere.resubscribe(client)
        self._subscribed = self.topics
        if old is not None and old != self.topics and client.session_present:
            await broker_calls.unsubscribe(client, topic_names(old))

    def _outage_over(self) -> None:
        """The broker link is back: the outage ends now, and its last wills are read as LINK_LOST until
        WILL_NEAR_OUTAGE_S later (orbitrig.dashboard.link_lost); the pages get the reading then and now."""
        if self.outage is None or self.outage.end is not None:
            return
        self.outage.end = time.monotonic()
        self._link_lost_anew()
        self._end_grace()
        self._grace = asyncio.get_running_loop().call_later(WILL_NEAR_OUTAGE_S + 0.05, self._grace_over)

    def _grace_over(self) -> None:
        """WILL_NEAR_OUTAGE_S after the link came back: the pages get the wills that came with the outage as
        `offline` now (their services not back)."""
        self._grace = None
        self._link_lost_anew()

    def _end_grace(self) -> None:
        """No grace pending: an outage begun anew (its reading holds until its link is back), or the session closed."""
        if self._grace is not None:
            self._grace.cancel()
            self._grace = None

    def _link_back(self, caught_up: bool) -> None:
        """The broker link is back after a drop: the pages learn whether the results published meanwhile
        come now (the broker kept the session's queue) or may be missing (marked in the results)."""
        if self._down_since is None:
            return
        message, self._down_since = gap_message(self._down_since, caught_up), None
        why = "caught up" if caught_up else "not kept by the broker: results may be missing"
        log.info(
            "session of %r: broker link back; what was published since %s: %s", self.user, message["data"]["from"], why
        )
        if not caught_up:
            self.results.append(message)
        self._broadcast(message)

    def _set_link(self, link: BrokerLink) -> None:
        if link != self.link:
            self.link = link
            log.info("session of %r: broker link %s", self.user, link)
            self._broadcast({"type": FeedType.LINK, "link": link})

    async def close(self, reason: str) -> None:
        self.closed = True
        self._end_grace()
        subscribing = self._stop_resubscribing()
        if subscribing is not None:
            await asyncio.gather(subscribing, return_exceptions=True)
        self._broadcast({"type": FeedType.SIGNED_OUT, "reason": reason})
        if self._task is not None:
            if self._end_broker_session():
                await asyncio.wait({self._task}, timeout=1.0)  # ends by itself once disconnected
            self._task.cancel()
            await asyncio.gather(self._task, return_exceptions=True)
        self._client = None

    def _end_broker_session(self) -> bool:
        """Disconnect, the broker forgetting the session (nothing queued for it any more); False without
        a connection (a session the broker kept expires after ``catch_up_s``)."""
        client = self._client
        if client is None:
            return False
        with contextlib.suppress(Exception):  # the link went meanwhile
            client.end_session()
        return True
