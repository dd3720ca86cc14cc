"""What a dashboard session reads (a mixin of orbitrig.dashboard.session.Session): the messages
of the rig watched, kept as what a page needs to draw the present at once (the retained status,
the latest progress (a run's status names it: a session signed in mid-run has it at once) and
live payloads, the results and the run's warnings so far, the trends and the alarms), and fanned
out to the session's browser feeds; the replies and acknowledgements that answer its commands
(orbitrig.dashboard.outgoing).

The alarms are the rig's book on the dashboard server (orbitrig.dashboard.alarms.AlarmShelf),
shared by the sessions watching it: whichever session applies a change, every one watching the
rig sends its pages the same messages.

Each status and each rig listed goes to the pages with the session's reading of an `offline`:
``link_lost``, its last will that came with a broker outage the session saw (orbitrig.dashboard.link_lost),
so that a page loaded at any time says what the session's refusals say; sent again as that reading
changes (an outage begun, ended, its grace over: orbitrig.dashboard.session).
"""

from __future__ import annotations

import asyncio
import collections
import logging
import time
from typing import Any, Callable

import orbitrig.service.protocol as proto
import rigunits
from orbitrig.dashboard.alarms import AlarmBook, AlarmShelf
from orbitrig.dashboard.catchup import Via
from orbitrig.dashboard.elsewhere import ElsewhereReplies
from orbitrig.dashboard.feed import BrokerLink, Feed, FeedType, written
from orbitrig.dashboard.finite import read_finite
from orbitrig.dashboard.lifted import typeset_note, typeset_result, typeset_status
from orbitrig.dashboard.link_lost import Outage, link_lost
from orbitrig.dashboard.rigs import RigDirectory
from orbitrig.dashboard.trend import TrendHistory

log = logging.getLogger("orbitrig.dashboard")

NOTES_KEPT = 100  # the rig's latest warnings a page gets when it (re)loads: as many as its events list shows
TREND_RESEND = 300  # the run's trend view (thinned by the server) goes to the pages again every this many samples


class Incoming:
    """The reading half of a session: the rig watched as its pages see it."""

    user: str
    settings: Any  # DashboardSettings
    shelf: AlarmShelf
    topics: proto.Topics
    rigs: RigDirectory
    link: BrokerLink
    feeds: set[Feed]
    _pending: dict[str, asyncio.Future]
    _elsewhere: ElsewhereReplies
    outcomes: collections.deque[dict]
    status: dict | None
    progress: dict | None
    live: dict | None
    #: a reply no call waits for any more (orbitrig.dashboard.outgoing.Outgoing.late_reply)
    late_reply: Callable[[dict], bool]
    #: the latest broker outage the session saw (orbitrig.dashboard.link_lost)
    outage: Outage | None
    #: the rig whose subscriptions the broker confirmed (orbitrig.dashboard.session)
    _subscribed: proto.Topics | None
    #: the topic of the message being read (None: none): the log names it for a message that cannot be written
    reading: str | None = None
    #: the fields of the payload being read that came as NaN or infinity, read as null (orbitrig.dashboard.finite);
    #: an instance's own list from _forget_rig on, reassigned per payload, never changed in place
    non_finite: list[str]

    def _forget_rig(self) -> None:
        """Drop what the session knows of the rig it watched."""
        self.status = self.progress = self.live = None
        self.status_at: float | None = None  # time.monotonic() the status was first heard (said again: kept)
        self.view_run: str | None = None  # the run of the progress and live payloads kept (_forget_run_view)
        self.live_at = 0.0  # time.monotonic() when the live payload came
        # the results so far and the gaps where some may be missing, as feed messages (result, gap)
        self.results: collections.deque[dict] = collections.deque(maxlen=500)
        self.notes: collections.deque[dict] = collections.deque(maxlen=NOTES_KEPT)  # the runs' warnings (note)
        self.endings: collections.deque[dict] = collections.deque(maxlen=NOTES_KEPT)  # how runs ended (ending)
        self.status_seen: int | None = None  # the session's place in the rig's alarm book (AlarmBook.on_status)
        self.trend = TrendHistory(self.settings.trend_period, self.settings.trend_recent_s)
        self.trend_samples = 0
        self.alarms_seen = -1  # the version of the rig's alarm book the pages have
        self.own_status_heard = False  # a status came by the rig's own subscription (Via.WATCHED) since it was chosen
        #: the status the pages have that is to come again by the rig's own subscription (read from the rigs' copy
        #: meanwhile, or the retained one a subscription made again hands on): that copy is not sent again
        self.status_expected: dict | None = None
        self.status_non_finite: list[str] = []  # the fields of the status kept that came as NaN or infinity
        self.non_finite = []
        self.non_finite_said: set[tuple[str, tuple[str, ...]]] = set()  # (topic, fields) logged: each once

    @property
    def alarms(self) -> AlarmBook:
        """The latched alarms of the rig watched (the dashboard server's book, not the session's)."""
        return self.shelf.book(self.topics.prefix)

    def _alarms_changed(self) -> None:
        """Send the pages the rig's alarms when its book changed since they got it (whichever
        session applied the change: every session watching the rig gets the same messages)."""
        book = self.alarms
        if book.version != self.alarms_seen:
            self.alarms_seen = book.version
            self._broadcast({"type": FeedType.ALARMS, "data": book.listing()})

    def adopt(self, peers: Any) -> None:
        """Start from the trends of the first of ``peers`` (sessions) watching the same rig; the alarms
        are the rig's own book."""
        peer = next((p for p in peers if p is not self and p.topics == self.topics), None)
        if peer is not None:
            self.trend.seed(peer.trend)
            self._broadcast({"type": FeedType.TREND_HISTORY, "data": self.trend.history()})
        self._alarms_changed()

    def _on_message(self, topic: str, raw: Any, via: frozenset[int] = frozenset()) -> None:
        """A message of the broker; ``via``: the identifiers of the subscriptions it came by (catchup.Via)."""
        raw = raw if isinstance(raw, (bytes, bytearray, str)) else b""
        rig_id = self.rigs.rig_of(topic)
        if not raw:  # a retained status cleared: the rig is no more listed, nor shown with the status it had
            if rig_id is not None and self.rigs.forget(rig_id):
                self._broadcast(self._rigs_message())
            if topic == self.topics.status and self.status is not None:
                self._status_cleared()
            return
        data = self._payload(topic, raw)
        if data is None:
            return
        self.reading = topic
        try:
            self._read(topic, data, rig_id, len(raw), via)
        finally:
            self.reading, self.non_finite = None, []

    def _status_cleared(self) -> None:
        """The watched rig's retained status cleared (an empty retained payload): the session forgets the rig's view
        and the pages clear theirs (a ``rig`` message), showing it as a rig with no status, as a page loaded now
        would; its alarms (the rig's book) are sent again."""
        log.info(
            "session of %r: the retained status of %s cleared: shown with no status", self.user, self.topics.prefix
        )
        self._forget_rig()
        self._broadcast({"type": FeedType.RIG, "prefix": self.topics.prefix})
        self._alarms_changed()

    def _payload(self, topic: str, raw: bytes | bytearray | str) -> dict | None:
        """The JSON object of a message, its NaN and infinities null (their fields in ``non_finite``, said in the
        log once per topic and fields); None: not a JSON object."""
        try:
            data, non_finite = read_finite(raw)
        except (ValueError, RecursionError):
            return None
        if not isinstance(data, dict):
            return None
        self.non_finite = non_finite  # until the payload is read (_on_message)
        if self.non_finite and (topic, tuple(self.non_finite)) not in self.non_finite_said:
            if len(self.non_finite_said) >= 256:
                self.non_finite_said.clear()
            self.non_finite_said.add((topic, tuple(self.non_finite)))
            fields = ", ".join(self.non_finite)
            log.warning("session of %r: %s came with NaN or infinity in %s: read as null", self.user, topic, fields)
        return data

    def _marked(self, message: dict) -> dict:
        """A feed message of the payload being read, with the fields that came as NaN or infinity (``non_finite``)."""
        return {**message, "non_finite": self.non_finite} if self.non_finite else message

    def _read(self, topic: str, data: dict, rig_id: str | None, size: int, via: frozenset[int]) -> None:
        """The payload of a message of the broker read (_on_message); ``size``: bytes of its JSON text."""
        t = self.topics
        if rig_id is not None and self.rigs.on_status(rig_id, data, size, self.non_finite):
            self._broadcast(self._rigs_message())
        if via and Via.WATCHED not in via and not self._status_from_rigs(topic):
            return  # the rigs' copy of a status: listed; the rig's own copy is read
        if topic == t.status and self._heard_before(data, via):
            return
        if topic == t.status:
            self._on_status(data, rig_id)
        elif topic == t.ack:
            self._resolve(data)
            self.alarms.on_ack(data)
            self._alarms_changed()
        elif topic == t.progress:
            self.progress = data
            self._broadcast(self._marked({"type": FeedType.PROGRESS, "data": data}))
        elif topic == t.live:
            self.live, self.live_at = data, time.monotonic()
            self._broadcast(self._marked({"type": FeedType.LIVE, "data": data}))
            self._trend(data)
        elif topic == t.result:  # stamped with when it came: its warnings are listed at that time, also on a reload
            result = {"type": FeedType.RESULT, **typeset_result(data, self.settings.typeset)}
            self._keep(self.results, self._marked({**result, "at": rigunits.now_iso()}))
        elif topic == t.note:
            self._keep(self.notes, self._marked({"type": FeedType.NOTE, **typeset_note(data, self.settings.typeset)}))
        elif topic == t.reply or self._elsewhere.is_reply(topic):  # also another rig's: a stop or abort sent there
            self._resolve(data)

    def _on_status(self, data: dict, rig_id: str | None) -> None:
        """A status of the rig watched: kept, sent to the pages, its run's end, progress and alarms applied."""
        self._forget_run_view(data)
        if data != self.status:  # the retained copy handed on again after an outage: heard before
            self.status_at = time.monotonic() if self.status is not None else self._first_heard(rig_id)
        self.status, self.status_non_finite = data, self.non_finite
        self._broadcast(self._status_message(data))
        self._keep_ending(data)
        self._status_progress(data)
        _, self.status_seen = self.alarms.on_status(data, self.status_seen)
        self._alarms_changed()

    def _read_listed(self, rig_id: str) -> None:
        """The rig chosen is not subscribed to yet: its status as the rigs listed it last is read as its status
        (the rigs' copy, below), unless one came meanwhile; the retained copy its subscription hands on is then
        not sent again (status_expected)."""
        listed = self.rigs.latest.get(rig_id)
        if listed is not None and self.status is None and self._status_from_rigs(self.topics.status):
            self._heard_before(listed, frozenset({Via.RIGS}))
            self.non_finite = self.rigs.latest_non_finite.get(rig_id, [])  # its fields named as a copy read now
            try:
                self._on_status(listed, rig_id)
            finally:
                self.non_finite = []

    def _status_from_rigs(self, topic: str) -> bool:
        """The rigs' copy of the watched rig's status is read as its status while the broker has not confirmed the
        rig's own subscription (orbitrig.dashboard.session.Session._resubscribe) and no status came by it: without
        it the page would hear nothing of the rig it shows until the next reconnection."""
        subscribed = self._subscribed == self.topics
        return topic == self.topics.status and not subscribed and not self.own_status_heard

    def _heard_before(self, data: dict, via: frozenset[int]) -> bool:
        """The status copy is one the pages have already (status_expected, above); True: not read again. While the
        rig's subscription is not confirmed each status read is expected again: every attempt's SUBSCRIBE has the
        broker hand on the retained one, and an attempt given up may have its copy come after the next began."""
        if via and Via.WATCHED not in via:
            self.status_expected = data  # read from the rigs' copy: the rig's own copy of it comes once subscribed
            return False
        self.own_status_heard = True
        if self.status_expected is not None and data == self.status_expected:
            return True  # still expected: another attempt's retained copy of it may follow
        self.status_expected = data if self._subscribed != self.topics else None
        return False

    def _keep(self, kept: collections.deque[dict], message: dict) -> None:
        """A result or warning kept for the pages that (re)load, and sent to those open."""
        same = {**message, "at": None}
        if any({**m, "at": None} == same for m in kept):  # a QoS 1 message handed on again (after a reconnection)
            return
        kept.append(message)
        self._broadcast(message)

    def _keep_ending(self, status: dict) -> None:
        """A run's closing status (``idle`` or ``faulted``, naming the run) kept, once, for the pages that
        (re)load: they list how each run ended at its time (the open pages have it as the status)."""
        if status.get("state") in proto.ENDED and status.get("run_id"):
            ending = {"type": FeedType.ENDING, **typeset_status(status, self.settings.typeset)}
            if ending not in self.endings:  # a QoS 1 status handed on again (after a reconnection)
                self.endings.append(ending)

    def _forget_run_view(self, status: dict) -> None:
        """The progress and live payloads go when the run ends or another run's status comes. An ``offline``
        status changes no run: its ``run_id`` may be the last will's (the run of the service's connection),
        and a service that comes back goes on with the run it had (its status, said again as it reconnects,
        names the run's latest progress)."""
        state, run_id = status.get("state"), status.get("run_id")
        if state == proto.OFFLINE:
            return
        if state in proto.ENDED or run_id != self.view_run:
            self.progress = self.live = None
        self.view_run = run_id

    def _status_progress(self, status: dict) -> None:
        """The progress a run's status names (the run's latest as the status was said: docs/protocols/mqtt.md)
        is the present one when it is of the run the status names (not one that ends it, nor ``offline``);
        progress messages supersede it. A session that signs in while the run waits for the operator or is
        paused has no other until measuring resumes."""
        progress, run_id = status.get("progress"), status.get("run_id")
        ours = isinstance(progress, dict) and run_id is not None and progress.get("run_id") == run_id
        if ours and status.get("state") not in (*proto.ENDED, proto.OFFLINE):
            self.progress = progress
            self._broadcast({"type": FeedType.PROGRESS, "data": progress})

    def _resolve(self, data: dict) -> None:
        """A reply (or this session's own acknowledgement back from the broker) for a waiting call."""
        fut = self._pending.pop(str(data.get("id")), None)
        if fut is None:
            self.late_reply(data)
        elif not fut.done():
            fut.set_result(data)

    def _trend(self, live: dict) -> None:
        sample = self.trend.add(live, time.time())
        if sample is None:
            return
        self.trend_samples += 1
        self._broadcast({"type": FeedType.TREND, "sample": sample, "run_id": self.trend.run_id})
        if self.trend_samples % TREND_RESEND == 0:
            self._broadcast({"type": FeedType.TREND_HISTORY, "data": {**self.trend.history(), "recent": None}})

    def _first_heard(self, rig_id: str | None) -> float:
        """time.monotonic() the first status of the rig watched (since it was chosen) was first heard: when the
        rigs listed heard it (a rig chosen after a broker outage, its retained last will listed long before, did
        not come with the outage), else now."""
        listed = self.rigs.heard_at.get(rig_id) if rig_id is not None else None
        return time.monotonic() if listed is None else listed

    def _status_message(self, status: dict) -> dict:
        """The feed message of the rig's status, with whether it is a last will of a broker outage (link_lost)."""
        lost = link_lost(status, self.status_at, self.outage)
        message = {"type": FeedType.STATUS, **typeset_status(status, self.settings.typeset), "link_lost": lost}
        return {**message, "non_finite": self.status_non_finite} if self.status_non_finite else message

    def _rigs_message(self) -> dict:
        """The feed message of the rigs listed, each with whether its status is a last will of a broker outage."""
        listing = self.rigs.listing()
        for rig_id, seen in listing.items():
            seen["link_lost"] = link_lost(seen, self.rigs.heard_at.get(rig_id), self.outage)
        return {"type": FeedType.RIGS, "data": listing}

    def _link_lost_anew(self) -> None:
        """The pages get the rig's status and the rigs listed again: how an offline is read changed (an outage
        begun or ended, or its grace over: orbitrig.dashboard.link_lost)."""
        if self.status is not None:
            self._broadcast(self._status_message(self.status))
        self._broadcast(self._rigs_message())

    def _broadcast(self, message: dict) -> None:
        """``message`` to every page of the session, its JSON text written once (feed.written; one that cannot be
        is dropped, the log naming the topic read)."""
        if not self.feeds:
            return
        json_text = written(message, f" of {self.reading}" if self.reading else "")
        if json_text is None:
            return
        for feed in list(self.feeds):
            feed.put(message, json_text)

    def snapshot(self) -> list[dict]:
        """What a newly connected page needs to draw the present at once."""
        out: list[dict] = [
            {
                "type": FeedType.HELLO,
                "user": self.user,
                "prefix": self.topics.prefix,
                "reply_timeout": self.settings.reply_timeout,
                "tick": self.settings.tick,
                "names": dict(self.settings.names),  # how the plots name the channels (the report's names)
            },
            {"type": FeedType.LINK, "link": self.link},
            self._rigs_message(),
            *self.endings,  # how the runs ended, listed at their time
        ]
        if self.status is not None:
            out.append(self._status_message(self.status))
        if self.progress is not None:
            out.append({"type": FeedType.PROGRESS, "data": self.progress})
        out += list(self.results)  # the results so far, and where some may be missing
        out += list(self.notes)  # the runs' warnings (the page lists each once)
        out.append({"type": FeedType.TREND_HISTORY, "data": self.trend.history()})
        out.append({"type": FeedType.ALARMS, "data": self.alarms.listing()})
        if self.outcomes:
            out.append({"type": FeedType.OUTCOMES, "data": list(self.outcomes)})
        if self.live is not None:
            out.append({"type": FeedType.LIVE, "data": self.live, "age_s": time.monotonic() - self.live_at})
        return out
