"""Commands as they arrive from the broker: stop and abort at once, the rest
one at a time behind a bounded queue, a flood answered "busy" or dropped.

The broker hands the service every message on ``<prefix>/cmd`` through one
queue per client (mosquitto: ``max_queued_messages``), so a service that falls
behind an operator flooding commands has the broker drop messages, an abort
among them. Here nothing falls behind: :class:`CommandInbox` is the MQTT
client's incoming queue, filled as each message is read off the socket (on
the event loop, before anything else happens to it), so

- ``stop`` and ``abort`` are carried out there and then (a first look at
  ``cmd``, :func:`command_json.peek`), never behind other commands; on
  ``<prefix>/abort`` (subscribed at QoS 0, so the broker does not queue them
  behind the commands waiting for the service either) only they are taken;
- any other command waits in the queue, at most ``limit`` of them; the
  service takes them one at a time;
- they are carried out at most ``COMMAND_RATE`` a second;
- beyond that, a command is answered ``ok: false`` "busy" without being
  carried out (at most ``BUSY_RATE`` a second, and while fewer than
  ``REPLY_BACKLOG`` replies wait to be sent), else dropped unanswered; both
  are counted and logged at most once a second. A flood so costs the service
  little more than reading it;
- an empty message (an operator clearing a retained one) is never answered.

Each message on ``<prefix>/abort`` is read twice, once off each connection that
reads it (the main one and the abort connection, orbitrig.service.abort_link):
:class:`AbortCopies` pairs the two copies so that it is carried out and
answered once (orbitrig.service.abort_copies).
"""

from __future__ import annotations

import asyncio
import collections
import contextvars
import logging
import time
from collections.abc import Callable
from typing import Any

from orbitrig.service import command_json
from orbitrig.service import protocol as proto
from orbitrig.service.abort_copies import CLOCK, AbortCopies, Connection

log = logging.getLogger("orbitrig.service.inbox")

#: commands waiting to be carried out, at most
WAITING_LIMIT = 64
#: ordinary commands carried out per second, at most (an operator sends a few)
COMMAND_RATE = 200.0
#: "busy" replies per second, at most; beyond, an excess command is dropped unanswered
BUSY_RATE = 50.0
#: replies waiting to be sent beyond which an excess command is dropped unanswered
REPLY_BACKLOG = 256
#: commands carried out as they arrive (docs/protocols/mqtt.md: always accepted)
AT_ONCE = proto.ALWAYS_ACCEPTED
BUSY = "busy: {n} commands are waiting; this one was not carried out (send it again later)"


def _may_name_at_once(payload: bytes) -> bool:
    """False only if ``payload`` cannot name stop or abort (neither word, no escape)."""
    lower = payload.lower()
    return any(word in lower for word in _AT_ONCE_BYTES) or b"\\" in payload


_AT_ONCE_BYTES = tuple(name.encode() for name in AT_ONCE)


class Allowance:
    """At most ``rate`` events a second, ``burst`` at once (a token bucket)."""

    def __init__(self, rate: float, burst: float):
        self.rate, self.burst = rate, burst
        self._tokens, self._at = burst, time.monotonic()

    def take(self) -> bool:
        """Use one if one is left (True)."""
        now = time.monotonic()
        self._tokens = min(self.burst, self._tokens + (now - self._at) * self.rate)
        self._at = now
        if self._tokens < 1.0:
            return False
        self._tokens -= 1.0
        return True

    def wait_s(self) -> float:
        """s until the next one."""
        return max(0.0, (1.0 - self._tokens) / self.rate)


#: the CommandInbox (so: the connection) whose message is being taken in, if any
_reading: contextvars.ContextVar[Any] = contextvars.ContextVar("reading", default=None)


def _not_taken(look: command_json.Glance) -> str:
    """Why a message on the abort topic is refused there."""
    if look.name is None:
        return f"{look.problem}; the abort topic takes stop and abort, as JSON objects as on the command topic"
    return (
        f"only stop and abort are taken on the abort topic, not {look.name!r}: send other commands on the command topic"
    )


class CommandTriage:
    """What happens to each command as it arrives. ``handle(payload, retained)``
    carries one out and replies; ``reply(cid, error)`` sends a reply;
    ``reply_backlog()`` is the number of replies not yet sent."""

    def __init__(
        self,
        handle: Callable[..., None],
        reply: Callable[[str | None, str], None],
        reply_backlog: Callable[[], int],
        *,
        limit: int = WAITING_LIMIT,
    ):
        self._handle, self._reply, self._backlog = handle, reply, reply_backlog
        self.limit = limit
        #: received, at once (stop/abort), busy (answered, not carried out), dropped (unanswered)
        self.counts: collections.Counter[str] = collections.Counter()
        self._commands = Allowance(COMMAND_RATE, burst=16)
        self._busy = Allowance(BUSY_RATE, burst=BUSY_RATE)
        self._logged: collections.Counter[str] = collections.Counter()
        self._logged_at = 0.0
        self.copies = AbortCopies()
        #: called with its name after each stop or abort carried out at once (the drives' stop under way)
        self.after_at_once: Callable[[str], None] = lambda name: None

    def at_once(self, payload: bytes, retained: bool) -> bool:
        """Carry out a stop or abort now (True); False: the command is to wait its turn.
        An empty message (clearing a retained one) is dealt with: never answered."""
        self.counts["received"] += 1
        if not payload:
            log.debug("command topic: empty message (a retained message cleared): not answered")
            return True
        if not _may_name_at_once(payload):
            return False  # the cheap test first: a flood must cost as little as possible
        name = command_json.glance(payload).name
        if name not in AT_ONCE:
            return False
        self.counts["at once"] += 1
        self._handle(payload, retained=retained)
        self.after_at_once(name)
        return True

    def urgent(self, payload: bytes, retained: bool, *, via: Connection = Connection.MAIN) -> None:
        """A message on ``<prefix>/abort`` read off connection ``via``: a stop or abort
        is carried out now; anything else is refused there, with the reason (other
        commands belong on ``<prefix>/cmd``); an empty one (clearing a retained
        message) is not answered. The copy of a message the other connection delivered
        already is dropped (:class:`AbortCopies`): carried out and answered once. A
        retained one, handed over as a connection subscribes, is no copy: a retained stop
        or abort goes to ``handle`` (which carries it out once in the service's life),
        anything else is answered on the main connection only."""
        connection = _reading.get()
        if not payload or retained:
            self.copies.seen(via, connection)
            if not payload:
                log.info("abort topic: empty message (a retained message cleared) read off the %s connection", via)
                return
        elif not self.copies.first(via, payload, connection):
            self.counts["second copy"] += 1
            log.info(
                "abort topic: dropped the %s connection's copy of %r (carried out once already)", via, payload[:80]
            )
            return
        self.counts["received"] += 1
        look = command_json.glance(payload)
        if look.name in AT_ONCE:
            self.counts["at once"] += 1
            self._handle(payload, retained=retained)
            self.after_at_once(look.name)
            log.info("abort topic: %s read off the %s connection", look.name, via)  # after: the stop first
        elif not retained or via is Connection.MAIN:
            self._reply(look.id, _not_taken(look))

    async def turn(self) -> None:
        """Wait until the next ordinary command may be carried out (``COMMAND_RATE``);
        the socket is read in between."""
        while not self._commands.take():
            await asyncio.sleep(self._commands.wait_s())
        await asyncio.sleep(0)

    def shed(self, payload: bytes, retained: bool) -> bool:
        """A command read while ``limit`` wait, before it is decoded: answered busy or
        dropped (True), unless it may name stop or abort (False: taken in as usual)."""
        if _may_name_at_once(payload):
            return False
        self.counts["received"] += 1
        if payload:  # (an empty one clears a retained message: never answered)
            self.overflow(payload, retained)
        return True

    def overflow(self, payload: bytes, retained: bool) -> None:
        """A command beyond ``limit`` waiting: answered busy, or dropped."""
        if self._backlog() < REPLY_BACKLOG and self._busy.take():
            self.counts["busy"] += 1
            self._reply(command_json.glance(payload).id, BUSY.format(n=self.limit))
        else:
            self.counts["dropped"] += 1
        self._report()

    def _report(self) -> None:
        now = time.monotonic()
        if now - self._logged_at < 1.0:
            return
        busy, dropped = (self.counts[k] - self._logged[k] for k in ("busy", "dropped"))
        log.warning(
            "command flood: %d commands answered busy, %d dropped unanswered since the last report "
            "(%d received in all)",
            busy,
            dropped,
            self.counts["received"],
        )
        self._logged = collections.Counter(self.counts)
        self._logged_at = now

    def flush_report(self) -> None:
        """Log what the last report left out (call when the flood has passed)."""
        if self.counts["busy"] + self.counts["dropped"] > self._logged["busy"] + self._logged["dropped"]:
            self._logged_at = 0.0
            self._report()


class CommandInbox(asyncio.Queue):
    """The MQTT client's incoming-message queue (``aiomqtt.Client(queue_type=...)``):
    ``put_nowait`` runs for each message as it is read off the socket.
    ``take_now(message)`` True: dealt with already; else the message waits in
    the queue, or ``overflow(message)`` when ``maxsize`` wait already. Never
    raises (an exception here would end the connection).

    The client makes one for each connection, before it connects: ``opened_at`` (the
    pairing's clock, :class:`AbortCopies`) is when that connection began, and messages
    taken in are known to come off it. ``on_end`` is called when its reader is cancelled:
    aiomqtt does that when the connection ends (or the reading task is cancelled)."""

    def __init__(self, maxsize: int = 0, *, take_now: Callable[[Any], bool], overflow: Callable[[Any], object]):
        super().__init__(maxsize)
        self._take_now, self._overflow = take_now, overflow
        self.opened_at = next(CLOCK)
        self.on_end: Callable[[], None] | None = None

    def put_nowait(self, message: Any) -> None:
        reading = _reading.set(self)
        try:
            if self._take_now(message):
                return
            if self.full():
                self._overflow(message)
                return
            super().put_nowait(message)
        except Exception:  # one message must not end the link
            log.exception("a command could not be taken in")
        finally:
            _reading.reset(reading)

    async def get(self) -> Any:
        try:
            return await super().get()
        except asyncio.CancelledError:
            if self.on_end is not None:
                self.on_end()
            raise
