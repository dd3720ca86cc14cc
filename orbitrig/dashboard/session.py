"""One signed-in person of the dashboard: an MQTT connection AS THAT BROKER USER.

The broker authenticates the connection and its ACL decides what the person
may do: the dashboard adds no rights of its own. The password lives only in
this object (server-side memory) for the reconnections; it is never logged.

A :class:`Session` watches one rig of the broker at a time (``select_rig``) and keeps
what the page needs to draw itself at once (the retained status, the latest progress
and live payloads, the results so far, the trends and the alarms)
and fans every rig message out to the session's browser feeds. A command is
published with a correlation id and answered by the service's reply; a publish
the ACL drops silently (MQTT 3.1.1) gets no reply: after ``reply_timeout`` it is
reported as refused, not authorised (or "no reply: the rig service is offline"
when the service's status says so).
"""

from __future__ import annotations

import asyncio
import collections
import dataclasses
import json
import logging
import secrets
import time
from pathlib import Path
from typing import Any

import orbitrig.service.protocol as proto
from daq.backoff import Backoff
from orbitrig.dashboard.alarms import AlarmBook
from orbitrig.dashboard.feed import BrokerLink, Feed, FeedType
from orbitrig.dashboard.rigs import RigDirectory
from orbitrig.dashboard.throttle import ThrottlePolicy
from orbitrig.dashboard.trend import TrendHistory
from orbitrig.service.reconnect import credentials_refused, reconnecting

log = logging.getLogger("orbitrig.dashboard")

#: Commands the page may send and the fields each takes besides ``cmd``.
PAGE_COMMANDS = {
    "start": ("matrix",),
    "pause": (),
    "resume": (),
    "stop": (),
    "abort": (),
    "confirm": ("step",),
    "status": (),
}
NOT_AUTHORISED = "refused: not authorised"
#: a run has ended in these states: its progress and live view are forgotten
ENDED = (proto.RunState.IDLE, proto.RunState.FAULTED)
TREND_RESEND = 300  # the run's trend view (thinned by the server) goes to the pages again every this many samples


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
    idle_timeout: float = 1800.0
    reply_timeout: float = 3.0
    keepalive: int = 10
    sessions_per_user: int = 4
    throttle: ThrottlePolicy = ThrottlePolicy()
    request_timeout: float = 10.0
    trend_period: float = 1.0  # s between trend samples
    trend_recent_s: float = 1800.0  # s of recent trend samples kept (the run's own view is thinned instead)


class Session:
    """One browser session = one broker user's MQTT connection."""

    def __init__(self, settings: DashboardSettings, user: str, password: str):
        self.settings = settings
        self.user = user
        self.__password = password
        self.token = secrets.token_urlsafe(32)
        self.last_active = time.monotonic()
        self.link = BrokerLink.CONNECTING
        self.status: dict | None
        self.progress: dict | None
        self.live: dict | None
        self.topics = settings.topics  # the rig watched now (select_rig changes it)
        self.rigs = RigDirectory(settings.topics.prefix)
        self._forget_rig()
        self.feeds: set[Feed] = set()
        self._pending: dict[str, asyncio.Future] = {}
        self._client: Any = None
        self._task: asyncio.Task | None = None
        self.closed = False

    def __repr__(self) -> str:  # never the password
        return f"Session(user={self.user!r}, link={str(self.link)!r})"

    def _forget_rig(self) -> None:
        """Drop what the session knows of the rig it watched."""
        self.status = self.progress = self.live = None
        self.live_at = 0.0  # time.monotonic() when the live payload came
        self.results: collections.deque[dict] = collections.deque(maxlen=500)
        self.trend = TrendHistory(self.settings.trend_period, self.settings.trend_recent_s)
        self.trend_samples = 0
        self.alarms = AlarmBook()

    def adopt(self, peers: Any) -> None:
        """Start from the trends and alarms of the first of ``peers`` (sessions) watching the same rig."""
        peer = next((p for p in peers if p is not self and p.topics == self.topics), None)
        if peer is not None:
            self.trend.seed(peer.trend)
            self.alarms.seed(peer.alarms)
            self._broadcast({"type": FeedType.TREND_HISTORY, "data": self.trend.history()})
            self._broadcast({"type": FeedType.ALARMS, "data": self.alarms.listing()})

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
        if client is not None:
            try:
                await client.unsubscribe(f"{old.prefix}/#")
                await client.subscribe(f"{new.prefix}/#", qos=1)  # the new rig's retained status comes
            except Exception as err:  # noqa: BLE001 - aiomqtt errors: the connection loop subscribes again
                log.info("session of %r: subscription to %s deferred: %s", self.user, new.prefix, err)
        return {"ok": True, "prefix": new.prefix}

    def touch(self) -> None:
        self.last_active = time.monotonic()

    # -- connection --------------------------------------------------------------

    def _make_client(self) -> Any:
        import aiomqtt

        s = self.settings
        tls = aiomqtt.TLSParameters(ca_certs=str(s.tls_ca) if s.tls_ca else None) if s.tls else None
        return aiomqtt.Client(
            s.host,
            s.port,
            username=self.user,
            password=self.__password,
            identifier=f"mosq-orbitrig-dashboard-{self.user}-{self.token[:8]}",
            clean_session=True,
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
            async with self._make_client() as client:
                await client.subscribe(f"{self.topics.prefix}/#", qos=1)
                if self.rigs.pattern is not None:
                    await client.subscribe(self.rigs.pattern, qos=1)
                self._client, connected = client, True
                if not first.done():
                    first.set_result(None)
                self._set_link(BrokerLink.ONLINE)
                async for message in client.messages:
                    self._on_message(str(message.topic), message.payload)
            return True
        except aiomqtt.MqttError as err:
            self._client = None
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
            return connected

    def _set_link(self, link: BrokerLink) -> None:
        if link != self.link:
            self.link = link
            log.info("session of %r: broker link %s", self.user, link)
            self._broadcast({"type": FeedType.LINK, "link": link})

    async def close(self, reason: str) -> None:
        self.closed = True
        self._broadcast({"type": FeedType.SIGNED_OUT, "reason": reason})
        if self._task is not None:
            self._task.cancel()
            await asyncio.gather(self._task, return_exceptions=True)
        self._client = None

    # -- incoming ----------------------------------------------------------------

    def _on_message(self, topic: str, raw: Any) -> None:
        t = self.topics
        try:
            data = json.loads(raw if isinstance(raw, (bytes, bytearray, str)) else b"")
        except (ValueError, RecursionError):
            return
        if not isinstance(data, dict):
            return
        rig_id = self.rigs.rig_of(topic)
        if rig_id is not None and self.rigs.on_status(rig_id, data):
            self._broadcast({"type": FeedType.RIGS, "data": self.rigs.listing()})
        if topic == t.status:
            self._forget_run_view(data)
            self.status = data
            self._broadcast({"type": FeedType.STATUS, "data": data})
            if self.alarms.on_status(data):
                self._broadcast({"type": FeedType.ALARMS, "data": self.alarms.listing()})
        elif topic == t.ack:
            self._resolve(data)
            if self.alarms.on_ack(data):
                self._broadcast({"type": FeedType.ALARMS, "data": self.alarms.listing()})
        elif topic == t.progress:
            self.progress = data
            self._broadcast({"type": FeedType.PROGRESS, "data": data})
        elif topic == t.live:
            self.live, self.live_at = data, time.monotonic()
            self._broadcast({"type": FeedType.LIVE, "data": data})
            self._trend(data)
        elif topic == t.result:
            self.results.append(data)
            self._broadcast({"type": FeedType.RESULT, "data": data})
        elif topic == t.reply:
            self._resolve(data)

    def _forget_run_view(self, status: dict) -> None:
        """The progress and live payloads go when the run ends or another run's status comes."""
        run_id, old = status.get("run_id"), self.status
        if status.get("state") in ENDED or (old is not None and old.get("run_id") != run_id):
            self.progress = self.live = None

    def _resolve(self, data: dict) -> None:
        """A reply (or this session's own acknowledgement back from the broker) for a waiting call."""
        fut = self._pending.pop(str(data.get("id")), None)
        if fut is not None and not fut.done():
            fut.set_result(data)

    def _trend(self, live: dict) -> None:
        sample = self.trend.add(live, time.time())
        if sample is None:
            return
        self.trend_samples += 1
        self._broadcast({"type": FeedType.TREND, "sample": sample, "run_id": self.trend.run_id})
        if self.trend_samples % TREND_RESEND == 0:
            self._broadcast({"type": FeedType.TREND_HISTORY, "data": {**self.trend.history(), "recent": None}})

    def _broadcast(self, message: dict) -> None:
        for feed in list(self.feeds):
            feed.put(message)

    def snapshot(self) -> list[dict]:
        """What a newly connected page needs to draw the present at once."""
        out: list[dict] = [
            {"type": FeedType.HELLO, "user": self.user, "prefix": self.topics.prefix},
            {"type": FeedType.LINK, "link": self.link},
            {"type": FeedType.RIGS, "data": self.rigs.listing()},
        ]
        out += [
            {"type": k, "data": v}
            for k, v in ((FeedType.STATUS, self.status), (FeedType.PROGRESS, self.progress))
            if v is not None
        ]
        out += [{"type": FeedType.RESULT, "data": r} for r in self.results]
        out.append({"type": FeedType.TREND_HISTORY, "data": self.trend.history()})
        out.append({"type": FeedType.ALARMS, "data": self.alarms.listing()})
        if self.live is not None:
            out.append({"type": FeedType.LIVE, "data": self.live, "age_s": time.monotonic() - self.live_at})
        return out

    # -- commands ----------------------------------------------------------------

    async def command(self, request: dict) -> dict:
        """Publish one command as this user; the service's reply, or a refusal (without the name)."""
        name = request.get("cmd")
        if name not in PAGE_COMMANDS:
            return {"ok": False, "error": f"unknown command {name!r}"}
        body = {"cmd": name, "by": self.user}  # the signed-in user, recorded in the run
        for field in PAGE_COMMANDS[name]:
            value = request.get(field)
            if not isinstance(value, str) or not value:
                return {"ok": False, "error": f"field {field!r} is missing"}
            body[field] = value
        client = self._client
        if client is None:
            return {"ok": False, "error": "no connection to the broker: try again when it is back"}
        cid = f"dash-{secrets.token_hex(6)}"
        topics = self.topics  # stop and abort on their own topic: no flood holds them back
        fut = asyncio.get_running_loop().create_future()
        self._pending[cid] = fut
        t0 = time.monotonic()
        try:
            await client.publish(
                topics.abort if name in proto.ALWAYS_ACCEPTED else topics.cmd,
                json.dumps({**body, "id": cid}),
                qos=proto.QOS_CMD,
                timeout=self.settings.reply_timeout,
            )
            reply = await asyncio.wait_for(fut, self.settings.reply_timeout)
        except (TimeoutError, asyncio.TimeoutError):
            return {"ok": False, "error": self._no_reply(name)}
        except Exception as err:  # noqa: BLE001 - aiomqtt errors: the link went away
            return {"ok": False, "error": f"not sent: {err}"}
        finally:
            self._pending.pop(cid, None)
        log.info(
            "%s by %r: %s (%.0f ms)",
            name,
            self.user,
            "ok" if reply.get("ok") else reply.get("error"),
            (time.monotonic() - t0) * 1e3,
        )
        return {"ok": bool(reply.get("ok")), "error": reply.get("error")}

    async def acknowledge(self, alarm_id: str) -> dict:
        """Acknowledge a latched alarm as this user: published on ``<prefix>/ack``; done when the
        broker hands it back (the ACL lets the user publish there), else refused."""
        alarm = self.alarms.alarms.get(alarm_id)
        if alarm is None:
            return {"ok": False, "error": f"acknowledge: no alarm {alarm_id!r}"}
        if alarm.acked_by is not None:
            return {"ok": True, "error": None}
        client = self._client
        if client is None:
            return {"ok": False, "error": "no connection to the broker: try again when it is back"}
        nonce = f"ack-{secrets.token_hex(6)}"
        fut = asyncio.get_running_loop().create_future()
        self._pending[nonce] = fut
        body = {"alarm": alarm_id, "by": self.user, "at": proto.iso8601(), "id": nonce}
        try:
            await client.publish(self.topics.ack, json.dumps(body), qos=1, timeout=self.settings.reply_timeout)
            await asyncio.wait_for(fut, self.settings.reply_timeout)
        except (TimeoutError, asyncio.TimeoutError):
            return {
                "ok": False,
                "error": f"{NOT_AUTHORISED}: acknowledge — user {self.user!r} may not "
                "acknowledge alarms of this rig (the broker dropped it)",
            }
        except Exception as err:  # noqa: BLE001 - aiomqtt errors: the link went away
            return {"ok": False, "error": f"acknowledge not sent: {err}"}
        finally:
            self._pending.pop(nonce, None)
        log.info("alarm %s acknowledged by %r", alarm_id, self.user)
        return {"ok": True, "error": None}

    def _no_reply(self, name: str) -> str:
        """Why a command got no reply (the page puts the command's name in front)."""
        if self.status is not None and self.status.get("state") == proto.OFFLINE:
            return "no reply: the rig service is offline"
        log.info("%s by %r: no reply within %.1f s (ACL)", name, self.user, self.settings.reply_timeout)
        return (
            f"{NOT_AUTHORISED} — user {self.user!r} may not command this rig "
            "(the broker dropped the command; no reply from the rig service)"
        )
