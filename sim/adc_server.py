"""Byte-stream transports of the A/D board: a TCP serial device server and a pty.

The board writes whole frames; a transport that cannot keep up drops whole
chunks (a reader then sees a seq gap), it never blocks the event loop. An
empty queue always takes the next chunk, however large. Loopback
only. A pty behaves like the board's serial port: the slave side is raw (no
line discipline), the simulator keeps it open so that readers may come and go.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import logging
import os
import termios
import time

from sim.pty import close_fds, open_raw_pty

log = logging.getLogger(__name__)

DEFAULT_BACKLOG = 1 << 20  # bytes queued per reader before chunks are dropped
STALE_AFTER = 0.5  # s (wall) without any byte taken: a serial line drops what nobody reads


class PtySink:
    """The board's serial port as a pseudo-terminal; ``path`` is the slave device."""

    def __init__(self, loop: asyncio.AbstractEventLoop, *, backlog: int = DEFAULT_BACKLOG // 4):
        self._loop = loop
        self._limit = backlog
        self._queue: collections.deque[memoryview] = collections.deque()
        self._queued = 0
        self._writer = False
        self.master: int | None = None
        self._slave: int | None = None
        self.path: str | None = None
        self.bytes_sent = 0
        self.chunks_dropped = 0
        self._progress = time.monotonic()
        self.open()

    def open(self) -> None:
        master, slave, self.path = open_raw_pty()
        self.master, self._slave = master, slave
        self._loop.add_reader(master, self._drain_input)

    @property
    def congested(self) -> bool:
        if self.master is None:
            return True
        self._forget_if_stale()
        return self._queued >= self._limit // 2

    def send(self, data: bytes) -> None:
        if self.master is None:
            return
        self._forget_if_stale()
        if self._queued and self._queued + len(data) > self._limit:
            self.chunks_dropped += 1
            return
        self._queue.append(memoryview(data))
        self._queued += len(data)
        if not self._writer:
            self._flush()

    def _flush(self) -> None:
        while self._queue and self.master is not None:
            head = self._queue[0]
            try:
                n = os.write(self.master, head)
            except BlockingIOError:
                break
            except OSError as err:  # EIO: the line is hung up
                log.debug("pty write failed: %s", err)
                self._queue.clear()
                self._queued = 0
                break
            self.bytes_sent += n
            self._queued -= n
            self._progress = time.monotonic()
            if n == len(head):
                self._queue.popleft()
            else:
                self._queue[0] = head[n:]
        master = self.master
        want = bool(self._queue) and master is not None
        if want and master is not None and not self._writer:
            self._loop.add_writer(master, self._flush)
            self._writer = True
        elif not want and self._writer:
            if master is not None:
                self._loop.remove_writer(master)
            self._writer = False

    def _forget_if_stale(self) -> None:
        """Nobody has read the line for a while: forget what waits in it (the
        tty input queue and the backlog), so a reader that opens the port
        later gets fresh frames, as on a real serial line."""
        if self._slave is None or self._queued < self._limit // 2 or time.monotonic() - self._progress <= STALE_AFTER:
            return
        with contextlib.suppress(OSError):
            termios.tcflush(self._slave, termios.TCIFLUSH)
        self._queue.clear()
        self._queued = 0
        self._progress = time.monotonic()

    def _drain_input(self) -> None:
        """Discard what a reader writes to the board (it has no commands)."""
        if self.master is not None:  # the reader is removed on hang-up, before master is cleared
            with contextlib.suppress(OSError):
                os.read(self.master, 65536)

    def hangup(self) -> None:
        """Close the line: the reader's port gets a hang-up (EIO / POLLHUP)."""
        if self.master is None:
            return
        self._loop.remove_reader(self.master)
        if self._writer:
            self._loop.remove_writer(self.master)
            self._writer = False
        close_fds(self.master, self._slave)
        self.master = self._slave = None
        self._queue.clear()
        self._queued = 0

    close = hangup


class TcpSink:
    """One connected client of the TCP serial device server."""

    def __init__(self, writer: asyncio.StreamWriter, *, backlog: int = DEFAULT_BACKLOG):
        self.writer = writer
        self._limit = backlog
        self.chunks_dropped = 0

    @property
    def congested(self) -> bool:
        return self.writer.transport.get_write_buffer_size() >= self._limit

    def send(self, data: bytes) -> None:
        if self.writer.transport.is_closing():
            return
        queued = self.writer.transport.get_write_buffer_size()
        if queued and queued + len(data) > self._limit:
            self.chunks_dropped += 1
            return
        self.writer.write(data)

    def close(self) -> None:
        self.writer.transport.abort()


class AdcServer:
    """Fan-out of the board's byte stream to a TCP serial device server and a pty."""

    def __init__(self, *, backlog: int = DEFAULT_BACKLOG):
        self._backlog = backlog
        self._server: asyncio.base_events.Server | None = None
        self.clients: set[TcpSink] = set()
        self.pty: PtySink | None = None
        self.port: int | None = None
        self._host = "127.0.0.1"
        self._reopen: asyncio.TimerHandle | None = None
        self._back: asyncio.Task[None] | None = None  # the board coming back after gone()

    async def start(self, *, host: str = "127.0.0.1", port: int = 0, pty: bool = True) -> None:
        self._host = host
        self._server = await asyncio.start_server(self._client, host, port)
        self.port = self._server.sockets[0].getsockname()[1]
        if pty:
            self.pty = PtySink(asyncio.get_running_loop())

    @property
    def url(self) -> str:
        return f"socket://127.0.0.1:{self.port}"

    @property
    def pty_path(self) -> str | None:
        return self.pty.path if self.pty is not None and self.pty.master is not None else None

    async def _client(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        sink = TcpSink(writer, backlog=self._backlog)
        self.clients.add(sink)
        try:
            while await reader.read(4096):  # the board ignores what it receives
                pass
        except (ConnectionError, OSError):
            pass
        finally:
            self.clients.discard(sink)
            writer.transport.abort()

    def wants_data(self) -> bool:
        """True when some reader could take more bytes now."""
        if any(not c.congested for c in self.clients):
            return True
        return self.pty is not None and not self.pty.congested

    def send(self, data: bytes) -> None:
        if not data:
            return
        for c in list(self.clients):
            c.send(data)
        if self.pty is not None:
            self.pty.send(data)

    def close_link(self, *, reopen_after: float | None = 1.0) -> None:
        """Fault: drop every TCP client and hang up the pty (reopened after
        ``reopen_after`` wall seconds, None: not; the path may change)."""
        for c in list(self.clients):
            c.close()
        self.clients.clear()
        if self.pty is not None and self.pty.master is not None:
            self.pty.hangup()
            if reopen_after is not None:
                self._reopen = asyncio.get_running_loop().call_later(reopen_after, self._reopen_pty)

    def gone(self, *, back_after: float | None = None) -> None:
        """Fault: the board goes away (its power, its cable): every TCP client dropped, nothing
        listening at its port (a connect is refused), the pty hung up; back on the same port and
        a new pty after ``back_after`` wall s (None: for good)."""
        for pending in (self._back, self._reopen):  # a return or a pty reopening planned before
            if pending is not None:
                pending.cancel()
        self._back = self._reopen = None
        server, self._server = self._server, None
        if server is not None:
            server.close()
        self.close_link(reopen_after=None)
        if back_after is not None:
            self._back = asyncio.get_running_loop().create_task(self._come_back(back_after), name="sim-adc-back")

    def back(self) -> None:
        """A board gone (gone()) comes back now."""
        if self._server is None and self.port is not None:
            self.gone(back_after=0.0)

    async def _come_back(self, after: float) -> None:
        await asyncio.sleep(after)
        try:
            self._server = await asyncio.start_server(self._client, self._host, self.port)
        except OSError as err:
            log.error("the A/D board cannot listen again at port %s: %s", self.port, err)
        self._reopen_pty()
        self._back = None

    def _reopen_pty(self) -> None:
        if self.pty is not None and self.pty.master is None:
            try:
                self.pty.open()
            except OSError as err:
                log.error("cannot reopen the A/D pty: %s", err)

    async def aclose(self) -> None:
        if self._reopen is not None:
            self._reopen.cancel()
        if self._back is not None:
            self._back.cancel()
        for c in list(self.clients):
            c.close()
        self.clients.clear()
        if self.pty is not None:
            self.pty.close()
        if self._server is not None:
            self._server.close()
            with contextlib.suppress(Exception):
                await asyncio.wait_for(self._server.wait_closed(), 2.0)
