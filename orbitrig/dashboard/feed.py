"""What the dashboard server sends a page over its feed (the WebSocket): the message types,
the states of the broker link, and the queue of messages waiting for one browser connection.
The page's own copy of these words: static/words.js."""

from __future__ import annotations

import asyncio
import collections
import time
from enum import StrEnum

import orbitrig.service.protocol as proto


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
#: progress, the next trend point; the run's trend is whole again in the next snapshot). Never these:
#: results, warnings (note), statuses, run ends, alarms, outcomes and the rest.
PLENTIFUL = frozenset({FeedType.TREND, FeedType.PROGRESS})


#: the most messages taken at once to be written to the page: the others wait in the queue, where a page
#: behind has its progress and trend points left out first (taken, a message is written whatever comes)
BATCH = 64


class Feed:
    """The messages waiting for one browser connection. Only the newest ``live`` payload is kept (a slow
    browser skips frames, never falls behind). At most ``limit`` others wait in the queue, and at most
    ``BATCH`` more taken to be written: beyond, the oldest waiting PLENTIFUL message is dropped and a ``gap``
    (its ``data.dropped``: kind -> count) goes before the next messages taken; when none of those is left the
    feed is ``behind`` (set) and takes nothing more: its connection is to be closed, the page connecting
    again gets the session's snapshot."""

    def __init__(self, limit: int = 2000):
        self.limit = limit
        self.queue: collections.deque[tuple[float, dict]] = collections.deque()  # (time.time() put, message)
        self.live: dict | None = None
        self.wake = asyncio.Event()
        self.behind = asyncio.Event()
        self.dropped: collections.Counter[str] = collections.Counter()
        self._dropped_span: tuple[float, float] | None = None  # s since the epoch: the first and last put dropped

    def put(self, message: dict) -> None:
        if self.behind.is_set():
            return
        if message.get("type") == FeedType.LIVE:
            self.live = message
        else:
            self.queue.append((time.time(), message))
            if len(self.queue) > self.limit:
                self._drop_plentiful()
        self.wake.set()

    def _drop_plentiful(self) -> None:
        """The oldest waiting PLENTIFUL message goes; none: the page is behind (``behind`` set)."""
        for i, (at, waiting) in enumerate(self.queue):
            if waiting.get("type") in PLENTIFUL:
                del self.queue[i]
                self.dropped[str(waiting["type"])] += 1
                self._dropped_span = (self._dropped_span[0] if self._dropped_span else at, at)
                return
        self.behind.set()

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
        """The next messages to write, once some wait: a gap of what was dropped first, then at most ``most``
        of the queue's oldest, then the newest ``live``. The rest stay queued (``wake`` stays set)."""
        await self.wake.wait()
        out = [self._gap()] if self._dropped_span is not None else []
        out += [self.queue.popleft()[1] for _ in range(min(most, len(self.queue)))]
        if self.live is not None:
            out.append(self.live)
            self.live = None
        if not self.queue:
            self.wake.clear()
        return out
