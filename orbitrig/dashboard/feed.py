"""What the dashboard server sends a page over its feed (the WebSocket): the message types,
the states of the broker link, and the queue of messages waiting for one browser connection.
The page's own copy of these words: static/words.js.

What waits for a page that reads slower than messages come (a starved tab, a slow path) is bounded
twice: in messages and in bytes (the JSON text the server writes), besides the snapshot its feed starts
with and the newest ``live`` payload (only the newest waits: it never cuts a page). Three sorts of message wait:

- SUPERSEDED kinds: the page draws each wholly from the newest of its kind, so only the newest waits
  (``rigs``: the selector is redrawn from the list; ``link``: the badge, banner and buttons; ``alarms``:
  the list is redrawn; ``trend_history``: the trend view, but one whose ``recent`` is null leaves the
  page's recent samples as they are, so it replaces only the waiting ones that are null too);
- PLENTIFUL kinds (``progress``, ``trend``): each superseded by the next of its kind but counted on the
  page (the events list says how many it did not show): left out, oldest first, only beyond a bound, and
  told by a ``gap``;
- every other kind is one the page must not miss: ``status`` too (the page lists a run's end, a fault and
  each run warning a status says as events; a status is not superseded by the next), ``result``, ``note``,
  ``ending``, ``gap``, ``outcome(s)``, ``rig`` (it clears the view between two rigs' messages),
  ``hello``, ``signed_out``. When only those wait beyond a bound the page is ``behind``: its connection is
  cut and its next one starts with the session's snapshot.
"""

from __future__ import annotations

import asyncio
import collections
import dataclasses
import itertools
import json
import logging
import time
from enum import StrEnum

import orbitrig.service.protocol as proto

log = logging.getLogger("orbitrig.dashboard")


class FeedType(StrEnum):
    """The ``type`` of a message to the page."""

    HELLO = "hello"
    LINK = "link"
    RIGS = "rigs"
    RIG = "rig"
    STATUS = "status"
    ENDING = "ending"  # a run's closing status kept by the session: a page (re)loaded lists how the run ended
    PROGRESS = "progress"
    LIVE = "live"
    RESULT = "result"  # with "at": when the dashboard server got it (UTC, its warnings listed at that time)
    NOTE = "note"  # a warning of the run (<prefix>/note)
    GAP = "gap"  # the broker link was down: whether the results published meanwhile came (caught_up)
    TREND = "trend"
    TREND_HISTORY = "trend_history"
    ALARMS = "alarms"
    OUTCOMES = "outcomes"
    OUTCOME = "outcome"  # one outcome that came later than its command's answer (a late reply to stop/abort)
    TICK = "tick"  # nothing else to send for a while: the page knows its feed is alive (defaults.TICK_S, --tick)
    SIGNED_OUT = "signed_out"


class BrokerLink(StrEnum):
    """The state of a session's connection to the broker, as the page shows it."""

    CONNECTING = "connecting"
    ONLINE = "online"
    UNREACHABLE = "broker unreachable"


#: the kinds a page may miss while it is behind: each is superseded by the next of its kind (the newest
#: progress, the next trend point; the run's trend is whole again in the next snapshot), and counted in a gap
PLENTIFUL = frozenset({FeedType.PROGRESS, FeedType.TREND})

#: the kinds of which only the newest waits: the page draws each wholly from the newest (module docstring)
SUPERSEDED = frozenset({FeedType.RIGS, FeedType.LINK, FeedType.ALARMS, FeedType.TREND_HISTORY})

#: the most messages taken at once to be written to the page: the others wait in the queue, where a page
#: behind has its progress and trend points left out first (taken, a message is written whatever comes)
BATCH = 64

#: what a trend history whose ``recent`` is null replaces (superseded_as): the run view alone
RUN_VIEW = "trend_history run view"

#: messages and bytes of JSON text at most waiting for one page besides its snapshot and the newest live payload
LIMIT = 2000
LIMIT_BYTES = 4_000_000


def text(message: dict) -> str:
    """The JSON text the server writes of ``message`` (ASCII: its length is its size in bytes); no NaN."""
    return json.dumps(message, allow_nan=False, default=str)


def written(message: dict, source: str = "") -> str | None:
    """The JSON text of ``message`` (:func:`text`), made once for every page that gets it; None: it cannot be
    written (a NaN that came some way other than the broker, whose payloads are made finite where the session
    reads them, orbitrig.dashboard.finite; a nesting too deep), and is dropped, said in the log with its kind and
    ``source`` (the topic it came on), never the end of a page's connection."""
    try:
        return text(message)
    except (ValueError, TypeError, RecursionError) as err:
        log.warning("a %s message%s cannot be written to the pages (%s): dropped", message.get("type"), source, err)
        return None


def superseded_as(message: dict) -> str | None:
    """Which newest waiting message ``message`` replaces (None: it replaces none): its kind; a trend history
    whose ``recent`` is null replaces only the waiting one that is null too (not a whole history before it)."""
    kind = message.get("type")
    if kind not in SUPERSEDED:
        return None
    if kind == FeedType.TREND_HISTORY and (message.get("data") or {}).get("recent") is None:
        return RUN_VIEW
    return str(kind)


@dataclasses.dataclass
class Waiting:
    """One message on a page's queue: when it was put (s since the epoch), its JSON text (:func:`written`), its size
    (bytes of that text) and whether it counts toward the bounds (False: one of the snapshot the feed began with,
    size 0)."""

    at: float
    message: dict
    text: str
    size: int
    counted: bool = True


class Feed:
    """The messages waiting for one browser connection. Only the newest ``live`` payload is kept (a slow
    browser skips frames, never falls behind), and of each SUPERSEDED kind only the newest. At most ``limit``
    messages and ``limit_bytes`` of JSON text wait besides the snapshot the feed began with (``start``) and the
    newest ``live``, and at most ``BATCH`` more taken to be written: beyond, the oldest waiting PLENTIFUL
    message is dropped and a ``gap`` (its ``data.dropped``: kind -> count) goes before the next messages taken;
    when none of those is left the feed is ``behind`` (set) and takes nothing more: its connection is to be
    closed, the page connecting again gets the session's snapshot."""

    def __init__(self, limit: int = LIMIT, limit_bytes: int = LIMIT_BYTES):
        self.limit, self.limit_bytes = limit, limit_bytes
        self.queue: collections.OrderedDict[int, Waiting] = collections.OrderedDict()  # by the order put
        self.counted = 0  # messages waiting that count toward ``limit`` (not the snapshot's)
        self.bytes = 0  # of the messages waiting that count toward ``limit_bytes`` (not the snapshot's, not live)
        self.live: tuple[dict, str] | None = None  # the newest live payload and its JSON text
        self.wake = asyncio.Event()
        self.behind = asyncio.Event()
        self.dropped: collections.Counter[str] = collections.Counter()
        self._dropped_span: tuple[float, float] | None = None  # s since the epoch: the first and last put dropped
        self._put = 0  # messages put so far: the next one's key in the queue
        self._plentiful: collections.OrderedDict[int, None] = collections.OrderedDict()  # their keys, oldest first
        self._newest: dict[str, int] = {}  # superseded_as -> the key of the newest waiting

    def start(self, snapshot: list[dict]) -> None:
        """Put the session's snapshot, a page's start: its messages wait beyond the bounds, counted toward
        neither (the last 500 results of a long run may be more than ``limit_bytes``: the page can always take
        them); once taken, or superseded, they leave the bounds as they were."""
        for message in snapshot:
            json_text = written(message, " of the snapshot")
            if json_text is None:
                continue
            if message.get("type") == FeedType.LIVE:
                self.live = message, json_text
            else:
                self._queue(message, json_text, counted=False)
        self.wake.set()

    def put(self, message: dict, json_text: str | None = None) -> None:
        """Queue ``message`` (``json_text``: its JSON text when made already, :func:`written`, once for all the
        session's pages; its length is its size; a ``live`` payload is counted toward neither bound: only the
        newest waits, never the cause of a cut). A message that cannot be written is dropped."""
        if self.behind.is_set():
            return
        json_text = written(message) if json_text is None else json_text
        if json_text is None:
            return
        if message.get("type") == FeedType.LIVE:
            self.live = message, json_text
        else:
            self._queue(message, json_text)
        while self.counted > self.limit or self.bytes > self.limit_bytes:
            if not self._drop_plentiful():
                break
        self.wake.set()

    def _queue(self, message: dict, json_text: str, counted: bool = True) -> None:
        key, self._put = self._put, self._put + 1
        size = len(json_text) if counted else 0
        self.queue[key] = Waiting(time.time(), message, json_text, size, counted)
        self.counted += counted
        self.bytes += size
        kind = message.get("type")
        if kind in PLENTIFUL and counted:  # a snapshot's progress left out would free nothing of the bounds
            self._plentiful[key] = None
        replaces = superseded_as(message)
        if replaces is None:
            return
        if replaces == FeedType.TREND_HISTORY:  # a whole history: the run view waiting before it goes too
            self._supersede(RUN_VIEW)
        self._supersede(replaces)
        self._newest[replaces] = key

    def _supersede(self, replaces: str) -> None:
        """The newest waiting message that ``replaces`` names goes (the page draws the same from the next)."""
        self._remove(self._newest.pop(replaces, -1))

    def _remove(self, key: int) -> Waiting | None:
        """The waiting message ``key`` off the queue (None: not waiting any more), its share of the bounds freed."""
        waiting = self.queue.pop(key, None)
        if waiting is not None:
            self._plentiful.pop(key, None)
            self.counted -= waiting.counted
            self.bytes -= waiting.size
        return waiting

    def _drop_plentiful(self) -> bool:
        """The oldest waiting PLENTIFUL message goes (True); none: the page is behind (``behind`` set)."""
        if not self._plentiful:
            self.behind.set()
            return False
        waiting = self._remove(next(iter(self._plentiful)))
        assert waiting is not None
        self.dropped[str(waiting.message["type"])] += 1
        self._dropped_span = (self._dropped_span[0] if self._dropped_span else waiting.at, waiting.at)
        return True

    def _gap(self) -> dict:
        """The feed message of what this page missed: the messages put from ``from`` to ``to`` dropped,
        kind -> how many (``caught_up``: every other message came)."""
        assert self._dropped_span is not None
        first, last = self._dropped_span
        data = {
            "from": proto.iso8601(first),
            "to": proto.iso8601(last),
            "caught_up": True,
            "dropped": dict(self.dropped),
        }
        self.dropped.clear()
        self._dropped_span = None
        return {"type": FeedType.GAP, "data": data}

    async def take(self, most: int = BATCH) -> list[dict]:
        """The next messages to write (:meth:`take_written`, without their texts)."""
        return [message for message, _ in await self.take_written(most)]

    async def take_written(self, most: int = BATCH) -> list[tuple[dict, str]]:
        """The next messages to write and their JSON texts, once some wait: a gap of what was dropped first, then
        at most ``most`` of the queue's oldest, then the newest ``live``. The rest stay queued (``wake`` stays set)."""
        await self.wake.wait()
        gap = self._gap() if self._dropped_span is not None else None
        out = [] if gap is None else [(gap, text(gap))]
        for key in list(itertools.islice(self.queue, most)):
            waiting = self._remove(key)
            assert waiting is not None
            out.append((waiting.message, waiting.text))
        if self.live is not None:
            out.append(self.live)
            self.live = None
        if not self.queue:
            self.wake.clear()
        return out
