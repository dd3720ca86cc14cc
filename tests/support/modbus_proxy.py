"""A real TCP proxy between a Modbus TCP client and the simulator's server: a slow network path.

Each client connection gets its own connection to the server. Every request frame (MBAP header
+ PDU) is forwarded as it comes, except those `hold(frame)` chooses: such a frame, and whatever
follows it on that connection (TCP keeps a connection's order), is held back: the client gets
no answer and times out. `release()` delivers the held frames, in the order they came, each on
its own server connection, even if the client has closed or reset its connection meanwhile
(bytes already in the path, or a gateway that queued the request, arrive all the same).
`release_after(seconds, when)` does it by itself `seconds` after a forwarded frame for which
`when(frame)` holds (the stop's word). `resets` counts client connections that ended in a reset
(RST) rather than a close (FIN). `cut()` resets every client connection and every new one until
`restore()`: a path broken, the link lost at once (held frames stay held). `answer(frame)`, if
given, rewrites each answer frame on its way back (a drive that answers another exception code
than the simulator's).
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Callable
from dataclasses import dataclass, field

Frame = bytes


def write_of(frame: Frame) -> tuple[int, int, int] | None:
    """(device id, address, value) of a write-single (FC06) request frame, else None."""
    if len(frame) < 12 or frame[7] != 6:
        return None
    return frame[6], int.from_bytes(frame[8:10], "big"), int.from_bytes(frame[10:12], "big")


def exception_code(frame: Frame, code: int, instead: int) -> Frame:
    """`frame` with its exception answer's code `code` made `instead` (any other frame as it is)."""
    if len(frame) == 9 and frame[7] & 0x80 and frame[8] == code:
        return frame[:8] + bytes([instead])
    return frame


def first_write(device_id: int, address: int, value: int) -> Callable[[Frame], bool]:
    """A `hold` that holds the first write-single of ``value`` to ``address`` of ``device_id`` (its
    retry, and every later one, gets through)."""
    held = [False]

    def hold(frame: Frame) -> bool:
        if write_of(frame) == (device_id, address, value) and not held[0]:
            held[0] = True
            return True
        return False

    return hold


@dataclass
class _Connection:
    upstream: asyncio.StreamWriter
    holding: bool = False
    tasks: list[asyncio.Task[None]] = field(default_factory=list)


class HoldingProxy:
    """Listens on 127.0.0.1 (any free port) for clients of the server at `port`."""

    def __init__(self, port: int, hold: Callable[[Frame], bool], answer: Callable[[Frame], Frame] | None = None):
        self.port, self.hold, self.answer = port, hold, answer
        self.held: list[tuple[_Connection, Frame]] = []
        self.released = asyncio.Event()
        self.resets = self.closes = 0
        self.cut_off = False
        self._clients: list[asyncio.StreamWriter] = []
        self._trigger: tuple[float, Callable[[Frame], bool]] | None = None
        self._server: asyncio.Server | None = None
        self._connections: list[_Connection] = []
        self._tasks: set[asyncio.Task[None]] = set()

    async def start(self) -> str:
        """Start listening; the URL for the client."""
        self._server = await asyncio.start_server(self._serve, "127.0.0.1", 0)
        return f"tcp://127.0.0.1:{self._server.sockets[0].getsockname()[1]}"

    def release_after(self, seconds: float, when: Callable[[Frame], bool]) -> None:
        """Release the held frames `seconds` after the first forwarded frame for which `when` holds."""
        self._trigger = (seconds, when)

    async def release(self) -> None:
        """Deliver the held frames, in order, on their server connections."""
        held, self.held = self.held, []
        for conn, frame in held:
            conn.upstream.write(frame)
            await conn.upstream.drain()
        self.released.set()

    def cut(self) -> None:
        """Reset every client connection, and each new one until `restore()`."""
        self.cut_off = True
        for writer in self._clients:
            writer.transport.abort()

    def restore(self) -> None:
        self.cut_off = False

    async def aclose(self) -> None:
        if self._server is not None:
            self._server.close()
        for task in self._tasks:
            task.cancel()
        for conn in self._connections:
            conn.upstream.close()
        await asyncio.gather(*self._tasks, return_exceptions=True)

    def _spawn(self, coro) -> asyncio.Task[None]:  # type: ignore[no-untyped-def]
        task = asyncio.get_running_loop().create_task(coro)
        self._tasks.add(task)
        return task

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        if self.cut_off:
            writer.transport.abort()
            return
        self._clients.append(writer)
        up_reader, up_writer = await asyncio.open_connection("127.0.0.1", self.port)
        conn = _Connection(up_writer)
        self._connections.append(conn)
        self._spawn(self._back(up_reader, writer))
        try:
            while True:
                head = await reader.readexactly(6)
                frame = head + await reader.readexactly(int.from_bytes(head[4:6], "big"))
                if conn.holding or self.hold(frame):
                    conn.holding = True
                    self.held.append((conn, frame))
                    continue
                up_writer.write(frame)
                await up_writer.drain()
                self._forwarded(frame)
        except ConnectionResetError:
            self.resets += 1
        except asyncio.IncompleteReadError:
            self.closes += 1
        finally:
            writer.close()
            if not conn.holding:  # held frames keep their server connection until delivered
                up_writer.close()

    def _forwarded(self, frame: Frame) -> None:
        if self._trigger is not None and self._trigger[1](frame):
            seconds, self._trigger = self._trigger[0], None
            self._spawn(self._release_in(seconds))

    async def _release_in(self, seconds: float) -> None:
        await asyncio.sleep(seconds)
        await self.release()

    async def _back(self, up_reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        """Answers back to the client (dropped once it has gone)."""
        with contextlib.suppress(ConnectionError, OSError, asyncio.IncompleteReadError):
            while True:
                if self.answer is None:
                    data = await up_reader.read(4096)
                else:  # frame by frame
                    head = await up_reader.readexactly(6)
                    data = self.answer(head + await up_reader.readexactly(int.from_bytes(head[4:6], "big")))
                if not data:
                    return
                if not writer.is_closing():
                    writer.write(data)
