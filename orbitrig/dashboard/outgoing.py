"""What a dashboard session publishes: the page's commands and alarm acknowledgements, as the
signed-in broker user (orbitrig.dashboard.session.Session), and what their outcomes say
(orbitrig.dashboard.commands).

Both are published at QoS 1 and the broker's PUBACK is awaited: under MQTT 5 a publish the
ACL refuses is answered with reason code 135, and only then is the outcome "not authorised".
A command is then answered by the service's reply (matched by its correlation id); without
one within ``reply_timeout`` its outcome is unknown. An acknowledgement is done when the
broker hands it back to the session (it subscribes to the rig's whole tree).

A command that could be carried out late must not be: while the rig's service is known offline
(its last will) no command other than stop and abort is published, and every other command
carries an MQTT 5 message expiry of ``ceil(reply_timeout)`` s, so the broker drops it instead
of handing it to a service that comes back after the page was told there is no answer. Stop and
abort carry none (the service subscribes to them at QoS 0: the broker keeps none for a service
that is away, and a late one only stops motion). A stop's or abort's reply that comes after the
reply timeout (within ``LATE_REPLY_S``) is still shown: as an outcome of its own, ``late``.

A stop or abort from a page showing a rig the session no longer watches goes to that rig (when the
dashboard knows it: commands.rig_for); its reply is read on that rig's reply topic for the while
it is awaited (orbitrig.dashboard.elsewhere), and its outcome names the rig (``rig``).
"""

from __future__ import annotations

import asyncio
import collections
import json
import logging
import math
import secrets
import time
from typing import Any

import orbitrig.service.protocol as proto
import orbitrig.service.broker_calls as broker_calls
from orbitrig.dashboard.alarms import AlarmBook
from orbitrig.dashboard.catchup import Via, tagged
from orbitrig.dashboard.commands import (
    EMERGENCY,
    NO_BROKER,
    command_body,
    late_reply,
    not_sent_offline,
    offline_now,
    refused,
    rig_mismatch,
    service_words,
    status_change,
    unknown,
    urgent_no_broker,
)
from orbitrig.dashboard.elsewhere import UNWATCHED, ElsewhereReplies
from orbitrig.dashboard.feed import FeedType
from orbitrig.dashboard.link_lost import Outage, link_lost
from orbitrig.dashboard.rigs import RigDirectory

log = logging.getLogger("orbitrig.dashboard")

#: the PUBACK's reason code of a publish the broker's ACL refuses (MQTT 5)
REFUSED_BY_ACL = 135
#: s after its reply timeout that a stop's or abort's late reply is still shown
LATE_REPLY_S = 60.0
_REREADS: set[asyncio.Task] = set()  # the status reads under way (a task needs a reference until it ends)


class Outgoing:
    """The publishing half of a session (a mixin of orbitrig.dashboard.session.Session)."""

    user: str
    settings: Any  # DashboardSettings
    topics: proto.Topics
    status: dict | None
    status_at: float | None  # time.monotonic() the status was first heard
    outage: Outage | None  # the latest broker outage the session saw
    rigs: RigDirectory
    _client: Any
    _pending: dict[str, asyncio.Future]
    #: stops and aborts without a reply in time: correlation id -> (command, time.monotonic() sent, rig
    #: it went to when the session watched another, else "")
    _late: dict[str, tuple[str, float, str]]
    _elsewhere: ElsewhereReplies
    #: the latest commands' outcomes, oldest first: a page loaded again shows them (snapshot)
    outcomes: collections.deque[dict]

    @property
    def alarms(self) -> AlarmBook:
        raise NotImplementedError

    def _broadcast(self, message: dict) -> None:
        raise NotImplementedError

    async def command(self, request: dict) -> dict:
        """Publish one command as this user (to the rig the page shows, ``request["rig"]``): the
        service's reply, or why there is none (without the command's name: the page adds it), and
        when (``at``, as the session keeps it among its outcomes); ``rig``: the rig a stop or abort
        went to when the session watches another."""
        body, prefix, error = command_body(request, self.user, self.topics.prefix, self._knows)
        if error is not None:
            return {"ok": False, "error": error}
        name, t0, elsewhere = body["cmd"], time.monotonic(), prefix != self.topics.prefix
        outcome = await self._publish_command(body, proto.Topics(prefix))
        if elsewhere:
            outcome["rig"] = prefix
        outcome["at"] = proto.iso8601()  # the page knows it again among the session's outcomes (snapshot)
        self.outcomes.append({"cmd": name, **outcome})
        log.info(
            "%s by %r: %s (%.0f ms)",
            name,
            self.user,
            "ok" if outcome["ok"] else outcome["error"],
            (time.monotonic() - t0) * 1e3,
        )
        return outcome

    def _knows(self, prefix: str) -> bool:
        """A rig of the dashboard: its own, or one of the rigs listed on the broker."""
        return prefix == self.settings.topics.prefix or self.rigs.state_of(prefix) is not None

    async def _publish_command(self, body: dict[str, str], topics: proto.Topics) -> dict:
        import aiomqtt

        from orbitrig.dashboard.puback import PublishUnconfirmed

        client, name = self._client, body["cmd"]
        urgent = name in proto.ALWAYS_ACCEPTED  # stop and abort on their own topic: no flood holds them back
        if client is None:
            again = f"not sent: {NO_BROKER}"
            return {"ok": False, "error": urgent_no_broker(name) if urgent else again}
        if not urgent and self._offline(topics):  # the broker would keep it for the service: carried out when back
            return {"ok": False, "error": not_sent_offline(self._link_lost(topics))}
        cid, before = f"dash-{secrets.token_hex(6)}", self.status
        fut = asyncio.get_running_loop().create_future()
        self._pending[cid] = fut
        wait = self.settings.reply_timeout
        rig = "" if topics == self.topics else topics.prefix  # another rig than the one watched: named in its outcome
        readable = not rig or self._elsewhere.watch(client, topics, cid)  # before the command goes
        if urgent and not rig:
            self._elsewhere.keep(topics, cid)  # its reply read on should the session leave the rig meanwhile
        try:
            code = await client.publish_qos1(
                topics.abort if urgent else topics.cmd,
                json.dumps({**body, "id": cid}),
                wait,
                expiry=None if urgent else math.ceil(wait),
            )
            if code == REFUSED_BY_ACL:
                return {"ok": False, "error": refused(self.user, "command this rig")}
            if code >= 0x80:  # another refusal of the broker (quota, packet too large, ...): not passed on
                return {"ok": False, "error": f"not sent: the broker refused the command (reason code {code})"}
            if urgent and self._offline(topics):
                return {"ok": False, "error": offline_now(name, self._link_lost(topics))}
            if not readable:
                return {"ok": False, "error": f"sent to rig {topics.prefix}, but {UNWATCHED}; {EMERGENCY}"}
            async with asyncio.timeout(wait):  # (3.11's wait_for can lose a cancellation)
                reply = await fut
        except PublishUnconfirmed as err:
            self._await_late(cid, name, topics, rig)
            return {"ok": False, "error": unknown(name, str(err), self._change(topics, before))}
        except (TimeoutError, asyncio.TimeoutError):
            self._await_late(cid, name, topics, rig)
            return {"ok": False, "error": self._no_reply(name, topics, before)}
        except aiomqtt.MqttError as err:  # the link went away before the command was handed over
            return {"ok": False, "error": f"{urgent_no_broker(name)} ({err})" if urgent else f"not sent: {err}"}
        finally:
            self._pending.pop(cid, None)
            self._release_later(cid)
        detail = reply.get("detail")  # what an ok command did, when the service says it
        if not reply.get("ok"):  # the service's own refusal (a run active, no such matrix): the page says so
            return {"ok": False, "error": reply.get("error") or "no reason given", "refused": True}
        return {"ok": True, "error": None, **({"detail": str(detail)} if detail else {})}

    def _await_late(self, cid: str, name: str, topics: proto.Topics, rig: str) -> None:
        """A command whose outcome is unknown: a stop's or abort's reply is still awaited a while (late_reply);
        the retained status is read again (the broker may have dropped messages of this session)."""
        now = time.monotonic()
        self._late = {k: v for k, v in self._late.items() if now - v[1] < self.settings.reply_timeout + LATE_REPLY_S}
        if name in proto.ALWAYS_ACCEPTED:
            self._late[cid] = (name, now, rig)
        if topics == self.topics and self._client is not None:
            task = asyncio.get_running_loop().create_task(self._reread_status(self._client, topics))
            _REREADS.add(task)
            task.add_done_callback(_REREADS.discard)

    async def _reread_status(self, client: Any, topics: proto.Topics) -> None:
        """Subscribe to the rig's status again: the broker replaces the subscription and hands the retained
        status over (the present state). No unsubscribe first: one whose acknowledgement came late would
        raise with the subscription gone, and the session would read nothing of the rig."""
        try:
            await broker_calls.subscribe(client, topics.status, 1, properties=tagged(Via.WATCHED))
        except Exception as err:  # noqa: BLE001 - aiomqtt errors: the link went; it subscribes again when back
            log.info("session of %r: status not read again: %s", self.user, err)

    def late_reply(self, data: dict) -> bool:
        """A reply to a stop or abort that came after its reply timeout: an outcome of its own (``late``),
        kept among the session's outcomes and sent to the pages. False: not one of them."""
        cid = str(data.get("id"))
        entry = self._late.pop(cid, None)
        if entry is None:
            return False
        name, sent, rig = entry
        self._release(cid)
        outcome = late_reply(name, data, time.monotonic() - sent, rig)
        self.outcomes.append(outcome)
        self._broadcast({"type": FeedType.OUTCOME, "data": outcome})
        log.warning("%s by %r: late reply: %s", name, self.user, outcome.get("error") or outcome.get("detail"))
        return True

    def _release_later(self, cid: str) -> None:
        """The reply topic of another rig read for ``cid`` goes now, or after the late-reply window."""
        if cid in self._late:
            asyncio.get_running_loop().call_later(self.settings.reply_timeout + LATE_REPLY_S, self._release, cid)
        else:
            self._release(cid)

    def _release(self, cid: str) -> None:
        self._elsewhere.release(self._client, cid, self.topics)  # the rig watched then keeps its own reply topic

    def _offline(self, topics: proto.Topics | None = None) -> bool:
        """The service of the rig watched (or of ``topics``, a rig of the listing) is known offline."""
        if topics is not None and topics != self.topics:
            return self.rigs.state_of(topics.prefix) == proto.OFFLINE
        return self.status is not None and self.status.get("state") == proto.OFFLINE

    def _link_lost(self, topics: proto.Topics) -> bool:
        """The offline status of the service of ``topics`` is its last will that came with a broker outage
        this session saw (orbitrig.dashboard.link_lost): its state is not known."""
        if topics != self.topics:
            status, heard = self.rigs.heard(topics.prefix)
            return link_lost(status, heard, self.outage)
        return link_lost(self.status, self.status_at, self.outage)

    def _change(self, topics: proto.Topics, before: dict | None) -> str | None:
        """The status change seen since a command was sent to ``topics`` (None: none, or another rig now)."""
        return status_change(before, self.status) if topics == self.topics else None

    def _no_reply(self, name: str, topics: proto.Topics, before: dict | None) -> str:
        """Why a command the broker took got no reply in time (the page puts the command's name in front)."""
        if self._offline(topics):
            return f"no reply: {service_words(self._link_lost(topics))}"
        log.info("%s by %r: no reply within %.1f s: outcome unknown", name, self.user, self.settings.reply_timeout)
        why = f"no reply from the rig service within {self.settings.reply_timeout:g} s"
        return unknown(name, why, self._change(topics, before))

    async def acknowledge(self, alarm_id: str, rig: Any) -> dict:
        """Acknowledge a latched alarm of the rig the page shows (``rig``) as this user: published on
        ``<prefix>/ack``; done when the broker hands it back; refused when the broker says so."""
        import aiomqtt

        from orbitrig.dashboard.puback import PublishUnconfirmed

        wrong_rig = rig_mismatch(rig, self.topics.prefix)
        if wrong_rig is not None:
            return {"ok": False, "error": f"acknowledge {wrong_rig}"}
        alarm = self.alarms.alarms.get(alarm_id)
        if alarm is None:
            return {"ok": False, "error": f"acknowledge: no alarm {alarm_id!r}"}
        if alarm.acked_by is not None:
            return {"ok": True, "error": None}
        client = self._client
        if client is None:
            return {"ok": False, "error": f"acknowledge: {NO_BROKER}"}
        nonce = f"ack-{secrets.token_hex(6)}"
        fut = asyncio.get_running_loop().create_future()
        self._pending[nonce] = fut
        body = {"alarm": alarm_id, "by": self.user, "at": proto.iso8601(), "id": nonce}
        wait = self.settings.reply_timeout
        try:
            if await client.publish_qos1(self.topics.ack, json.dumps(body), wait) == REFUSED_BY_ACL:
                return {"ok": False, "error": "acknowledge: " + refused(self.user, "acknowledge alarms of this rig")}
            async with asyncio.timeout(wait):
                await fut
        except (PublishUnconfirmed, TimeoutError, asyncio.TimeoutError):
            return {"ok": False, "error": f"acknowledge: not confirmed by the broker within {wait:g} s: try again"}
        except aiomqtt.MqttError as err:  # the link went away
            return {"ok": False, "error": f"acknowledge not sent: {err}"}
        finally:
            self._pending.pop(nonce, None)
        log.info("alarm %s acknowledged by %r", alarm_id, self.user)
        return {"ok": True, "error": None}
