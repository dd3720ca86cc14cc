"""A read deadline for every HTTP request of the dashboard (the slow-loris guard).

aiohttp waits for a request's head and body without a limit. `RequestDeadline` sits
between the socket and aiohttp's protocol: from a connection's opening (or a new
request's first byte) the head and its ``Content-Length`` body must arrive within
``limit`` s, or the connection is closed. Between requests an idle keep-alive
connection is left to aiohttp's ``keepalive_timeout``; a websocket upgrade (the
page's feed) and a chunked body end the watch of that connection.
"""

from __future__ import annotations

import asyncio
import logging
import re
from typing import Any

log = logging.getLogger("orbitrig.dashboard")

HEAD_END = b"\r\n\r\n"
MAX_HEAD = 64 * 1024  # a longer head is aiohttp's to refuse; the guard stops watching it
_LENGTH = re.compile(rb"(?im)^content-length:[ \t]*(\d+)[ \t]*\r?$")
_UNWATCHED = re.compile(rb"(?im)^(upgrade:|transfer-encoding:[^\r\n]*chunked)")


class RequestDeadline(asyncio.Protocol):
    """Wraps aiohttp's protocol `inner`; closes the connection when a request is not
    read in full within `limit` s (s, wall clock)."""

    def __init__(self, inner: Any, limit: float):
        self.inner, self.limit = inner, limit
        self.transport: asyncio.BaseTransport | None = None
        self.head = bytearray()
        self.body_left = 0
        self.watching = True
        self.timer: asyncio.TimerHandle | None = None

    def __getattr__(self, name: str) -> Any:  # what asyncio.Protocol does not define itself
        return getattr(self.inner, name)

    def pause_writing(self) -> None:
        """The socket's send buffer is full (a page not reading): aiohttp waits before it writes more, so a
        feed's messages wait in its queue (orbitrig.dashboard.feed.Feed, bounded), not in the transport's
        buffer without bound. asyncio.Protocol's own, a no-op, would come before ``__getattr__``."""
        self.inner.pause_writing()

    def resume_writing(self) -> None:
        self.inner.resume_writing()

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport
        self._arm()
        self.inner.connection_made(transport)

    def connection_lost(self, exc: Exception | None) -> None:
        self._disarm()
        self.inner.connection_lost(exc)

    def eof_received(self) -> bool | None:
        return self.inner.eof_received()

    def data_received(self, data: bytes) -> None:
        if self.watching:
            self._scan(memoryview(data))
        self.inner.data_received(data)

    def _scan(self, view: memoryview) -> None:
        while view and self.watching:
            self._arm()  # a request under way
            if self.body_left:
                n = min(self.body_left, len(view))
                self.body_left -= n
                view = view[n:]
                if not self.body_left:
                    self._disarm()
                continue
            start = max(0, len(self.head) - 3)
            self.head += view
            end = self.head.find(HEAD_END, start)
            if end < 0:
                if len(self.head) > MAX_HEAD:
                    self._stop_watching()
                return
            head, rest = bytes(self.head[:end]), bytes(self.head[end + 4 :])
            self.head.clear()
            if _UNWATCHED.search(head):
                self._stop_watching()
                return
            length = _LENGTH.search(head)
            self.body_left = int(length.group(1)) if length else 0
            if not self.body_left:
                self._disarm()
            view = memoryview(rest)

    def _arm(self) -> None:
        if self.timer is None:
            self.timer = asyncio.get_running_loop().call_later(self.limit, self._expired)

    def _disarm(self) -> None:
        if self.timer is not None:
            self.timer.cancel()
            self.timer = None

    def _stop_watching(self) -> None:
        self.watching = False
        self.head.clear()
        self._disarm()

    def _expired(self) -> None:
        self.timer = None
        peer = self.transport.get_extra_info("peername") if self.transport else None
        log.info("closed the connection of %s: a request not read in full within %g s", peer, self.limit)
        if isinstance(self.transport, asyncio.WriteTransport):
            self.transport.abort()
