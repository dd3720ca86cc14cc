"""CanReader: the frames of one CAN bus handed to a callback on the event loop; a bus that
fails is shut down, said once, and opened again until it opens.

python-can's ``Notifier`` on an event loop reads a bus that has a file descriptor (SocketCAN,
a serial adapter, serial-over-TCP) with ``loop.add_reader``, and a receive error there is
raised from the loop's callback every time the descriptor is readable, which a closed
connection always is: tens of thousands of tracebacks a second on the loop that polls the
drives, and the bus never read again. Here a receive error ends the reading at once; the bus
is shut down off the loop and opened again after ``RETRY_S``, then at growing intervals up to
``RETRY_MAX_S``. A readable descriptor is read until nothing waits on it: a loop held late
reads the frames queued meanwhile before any check looks at the node. A bus without a descriptor (python-can's ``virtual``) is read by a thread of
its own, which hands each frame to the loop.
"""

from __future__ import annotations

import asyncio
import logging
import select
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from daq.errors import DaqError

if TYPE_CHECKING:
    import can

log = logging.getLogger(__name__)

RETRY_S = 0.5  # s before the first attempt to open a failed bus again
RETRY_MAX_S = 5.0  # s between attempts at most
THREAD_POLL_S = 0.1  # s a reader thread waits for a frame before it looks whether to stop
#: frames read at most in one turn of the loop (a backlog of 2 s of the node's frames is about 80):
#: a bus that never stops being readable cannot hold the loop
BACKLOG_FRAMES = 1000


class CanReader:
    """Reads ``bus`` (already open; ``name`` in messages) into ``on_message`` on the running
    loop; ``reopen()`` opens the bus again after a failure (raising when it cannot).
    ``link_drops`` counts the failures, ``error`` says why the bus is down while it is."""

    def __init__(self, bus: can.BusABC, reopen: Callable[[], can.BusABC], on_message: Callable[[Any], None], name: str):
        import can  # the caller opened a bus: python-can is there

        self._errors: tuple[type[BaseException], ...] = (can.CanError, OSError, ValueError)  # pyserial's are OSError
        self._bus: Any = bus
        self._reopen = reopen
        self._on_message = on_message
        self.name = name
        self.link_drops = 0
        self.error: str | None = None
        self._loop = asyncio.get_running_loop()
        self._fd: int | None = None
        self._stop = threading.Event()
        self._retry: asyncio.Task[None] | None = None
        self._closed = False
        self._lock = threading.Lock()  # _closed and _opened, between close() and a thread's open
        self._opened: Any = None  # a bus opened again, not yet taken up by the loop
        self._start()

    def _start(self) -> None:
        try:
            fd = int(self._bus.fileno())
        except NotImplementedError:
            fd = -1
        if fd >= 0:
            self._fd = fd
            self._loop.add_reader(fd, self._readable)
        else:
            self._stop = threading.Event()
            name = f"orbitrig-can {self.name}"
            threading.Thread(target=self._receive, args=(self._bus, self._stop), name=name, daemon=True).start()

    def _readable(self) -> None:
        """The descriptor is readable: every frame waiting on it (or a failure). A loop held late
        (a starved host) finds the node's frames of that while queued; read one a turn, a check
        looking in between judged the node by a heartbeat age while its newer heartbeat lay unread."""
        for _ in range(BACKLOG_FRAMES):
            try:
                msg = self._bus.recv(0)
            except self._errors as err:
                self._failed(err)
                return
            if msg is not None:
                self._on_message(msg)
            if self._fd is None or not _waiting(self._fd):
                return

    def _receive(self, bus: Any, stop: threading.Event) -> None:
        """Reader thread of a bus without a descriptor."""
        while not stop.is_set():
            try:
                msg = bus.recv(THREAD_POLL_S)
            except self._errors as err:
                if not stop.is_set():
                    self._loop.call_soon_threadsafe(self._failed, err)
                return
            if msg is not None and not stop.is_set():
                self._loop.call_soon_threadsafe(self._on_message, msg)

    def _stop_reading(self) -> Any:
        """Stop reading; the bus to shut down (None when there is none)."""
        if self._fd is not None:
            self._loop.remove_reader(self._fd)
            self._fd = None
        self._stop.set()
        bus, self._bus = self._bus, None
        return bus

    def _failed(self, err: BaseException) -> None:
        if self._closed or self._bus is None:
            return
        bus = self._stop_reading()
        self.link_drops += 1
        self.error = f"{type(err).__name__}: {err}"
        log.error("CAN link %s lost (%s); opening it again every %g-%g s", self.name, self.error, RETRY_S, RETRY_MAX_S)
        self._retry = self._loop.create_task(self._open_again(bus), name=f"CAN {self.name} reopen")

    async def _open_again(self, failed: Any) -> None:
        await asyncio.to_thread(_shutdown, failed)
        delay = RETRY_S
        errors: tuple[type[BaseException], ...] = (DaqError, *self._errors)
        while True:
            await asyncio.sleep(delay)
            try:
                await asyncio.to_thread(self._open)
            except errors:  # still down: ``error`` keeps why the link was lost
                delay = min(2 * delay, RETRY_MAX_S)
                continue
            with self._lock:
                bus, self._opened = self._opened, None
            if bus is None:  # closed meanwhile: _open shut it down
                return
            self._bus, self.error = bus, None
            self._start()
            log.info("CAN link %s open again", self.name)
            return

    def _open(self) -> None:
        """Thread: open the bus again into ``_opened``; one that opens after ``close()`` is shut
        down here (close() cancels the waiting task, not the open: the bus would stay open)."""
        bus = self._reopen()
        with self._lock:
            if not self._closed:
                self._opened = bus
                return
        _shutdown(bus)

    def close(self) -> Any:
        """Stop reading and retrying (idempotent); the bus to shut down (the one read, or one just
        opened again), or None."""
        with self._lock:
            self._closed = True
            opened, self._opened = self._opened, None
        if self._retry is not None:
            self._retry.cancel()
            self._retry = None
        bus = self._stop_reading()
        return opened if bus is None else bus


def _waiting(fd: int) -> bool:
    """Bytes are waiting on descriptor `fd` now (no wait)."""
    try:
        return bool(select.select([fd], [], [], 0)[0])
    except (OSError, ValueError):  # closed meanwhile: the next read says so
        return False


def _shutdown(bus: Any) -> None:
    import can

    try:
        bus.shutdown()
    except (can.CanError, OSError) as err:  # a bus already broken may fail to close as well
        log.debug("CAN bus shutdown: %s", err)
