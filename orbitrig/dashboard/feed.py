"""What the dashboard server sends a page over its feed (the WebSocket): the message types,
the states of the broker link, and the queue of messages waiting for one browser connection.
The page's own copy of these words: static/words.js."""

from __future__ import annotations

import asyncio
import collections
from enum import StrEnum


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


class Feed:
    """The messages waiting for one browser connection; only the newest ``live``
    payload is kept (a slow browser skips frames, never falls behind)."""

    def __init__(self, limit: int = 2000):
        self.queue: collections.deque[dict] = collections.deque(maxlen=limit)
        self.live: dict | None = None
        self.wake = asyncio.Event()

    def put(self, message: dict) -> None:
        if message.get("type") == FeedType.LIVE:
            self.live = message
        else:
            self.queue.append(message)
        self.wake.set()

    async def take(self) -> list[dict]:
        await self.wake.wait()
        self.wake.clear()
        out = list(self.queue)
        self.queue.clear()
        if self.live is not None:
            out.append(self.live)
            self.live = None
        return out
