"""The pairing of the two copies of each message on ``<prefix>/abort``.

The service reads ``<prefix>/abort`` off two connections to the broker (the main one,
orbitrig.service.link, and the abort connection, orbitrig.service.abort_link), so each
message there reaches it twice: :class:`AbortCopies` pairs the copies so that each abort
is carried out and answered once (orbitrig.service.inbox asks it for every copy read).
"""

from __future__ import annotations

import collections
import dataclasses
import enum
import functools
import hashlib
import itertools
from typing import Any

#: copies of abort-topic messages kept per connection for pairing, at most: far beyond what one
#: connection can lag behind the other (the broker queues 10000 messages for a client,
#: config/mosquitto/mosquitto.conf), so an entry is given up only when its copy cannot come
COPIES_KEPT = 65536


class Connection(enum.StrEnum):
    """The service's two connections to the broker that read ``<prefix>/abort``."""

    MAIN = "main"  # the service's session: commands, and stop and abort as a fallback
    ABORT = "abort"  # its own account, <prefix>/abort alone (orbitrig.service.abort_link)


_OTHER = {Connection.MAIN: Connection.ABORT, Connection.ABORT: Connection.MAIN}
#: the order in which connections began and messages were read (the pairing's clock)
CLOCK = itertools.count()


@dataclasses.dataclass(frozen=True)
class _Copy:
    at: int  # CLOCK when it was read
    key: bytes  # the message's bytes (a digest of them)


def _key(payload: bytes) -> bytes:
    return hashlib.blake2b(payload, digest_size=16).digest()


class AbortCopies:
    """Each message on ``<prefix>/abort`` reaches the service twice, once on each connection
    that reads it, in either order: the first copy is carried out, the second dropped.

    The broker passes every message of the topic to both connections in the same order
    (QoS 0, at once), and each connection delivers what it gets in that order; a connection
    misses what was published before it subscribed (or while it was away: QoS 0 is not
    kept) and what its broker queue drops. So copies are matched in order, by their bytes,
    one to one (the same abort published twice is two aborts), and

    - a copy's match is the oldest copy of the other connection still waiting with the same
      bytes. The other's copies waiting before it, the reading connection has passed (its
      queue at the broker dropped them): they are given up; so are its own copies still
      waiting, which the other connection has passed;
    - a (re)connection (:meth:`seen`: a message off a new ``CommandInbox``) begins a new
      stream: the other's copies read before it began can never have their copy on it and
      are given up (it was not subscribed when they were published); its own copies still
      waiting become doubtful (the other connection may or may not deliver them);
    - where the order cannot tell (a copy with no match while the other connection's copies
      wait: one of the two missed messages, which one is not known), the copies concerned
      become doubtful (``_spent``): a doubtful copy, if it comes, is carried out again rather
      than dropped, and is not left waiting;
    - while the abort connection is down (``up``), a main connection's copy is carried out
      even when it matches: the abort connection may have missed it;
    - nothing expires with time; only a connection ``COPIES_KEPT`` messages behind the
      other (the broker would have dropped them) loses entries.

    Every rule that cannot be sure errs towards carrying a copy out (a second emergency
    stop, and a second reply) rather than dropping one that may be the only copy of an abort.
    """

    def __init__(self, kept: int = COPIES_KEPT):
        #: per connection: its copies carried out whose other copy has not been read (oldest first)
        self._waiting = {c: collections.deque[_Copy](maxlen=kept) for c in Connection}
        #: per connection: copies the other read that it may still deliver, the pairing unsure
        self._spent = {c: collections.deque[_Copy](maxlen=kept) for c in Connection}
        self._since = {c: -1 for c in Connection}  # CLOCK when its current connection began
        self._current: dict[Connection, Any] = {}  # its current connection (CommandInbox)
        #: subscribed: the main connection unless said otherwise; the abort one once it delivers
        self.up = {Connection.MAIN: True, Connection.ABORT: False}

    def seen(self, via: Connection, connection: Any = None) -> None:
        """A message read off ``connection`` of ``via`` (the CommandInbox of the MQTT client: one
        per connection); a new one: ``via`` has (re)connected (:meth:`opened`)."""
        if connection is None:
            self.up[via] = True  # (called without a connection: the one delivering is up)
        elif connection is not self._current.get(via):
            self._current[via] = connection
            self.opened(via, since=getattr(connection, "opened_at", None))
            if via is Connection.ABORT and hasattr(connection, "on_end"):  # (its reader ends with it)
                connection.on_end = functools.partial(self.closed, via, connection)

    def opened(self, via: Connection, since: int | None = None) -> None:
        """``via`` (re)connected at ``since`` (the pairing's clock; default: now): it cannot deliver
        what the other connection read before; its own copies still waiting become doubtful."""
        since = next(CLOCK) if since is None else since
        self._since[via] = since = max(self._since[via], since)
        self.up[via] = True
        other = _OTHER[via]
        theirs, spent = self._waiting[other], self._spent[via]
        for keep in (theirs, spent):
            kept = [c for c in keep if c.at > since]
            keep.clear()
            keep.extend(kept)
        self._spent[other].extend(self._waiting[via])
        self._waiting[via].clear()

    def closed(self, via: Connection, connection: Any = None) -> None:
        """``via``'s connection (``connection``, or whichever) ended: it delivers nothing more."""
        if connection is None or connection is self._current.get(via):
            self.up[via] = False

    def first(self, via: Connection, payload: bytes, connection: Any = None) -> bool:
        """True for the first copy of a message (carry it out), False for its second."""
        self.seen(via, connection)
        key, other = _key(payload), _OTHER[via]
        theirs, mine, spent = self._waiting[other], self._waiting[via], self._spent[via]
        doubtful = next((c for c in spent if c.key == key), None)
        if doubtful is not None:  # may be the copy of one carried out already: carried out again
            spent.remove(doubtful)
            if via is Connection.ABORT:  # or a new one: its main copy, if it comes, is not left waiting
                self._spent[other].append(_Copy(next(CLOCK), key))
            return True
        match = next((i for i, c in enumerate(theirs) if c.key == key), None)
        if match is not None:
            for _ in range(match + 1):  # its copy, and those before it: `via` passed them
                theirs.popleft()
            mine.clear()  # the other connection passed these: it read this message after them
            return not (via is Connection.ABORT or self.up[Connection.ABORT])
        now = _Copy(next(CLOCK), key)
        if theirs:  # one connection missed messages, which one cannot be told
            spent.extend(theirs)
            theirs.clear()
            self._spent[other].append(now)
        else:
            mine.append(now)
        return True
