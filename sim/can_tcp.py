"""A CAN bus between processes: python-can's `serial` framing over TCP.

python-can's `virtual` bus lives inside one process. Here every node, the
simulator's sensor node included, opens

    can.Bus(interface="serial", channel="socket://127.0.0.1:5010")

(pyserial's socket URL), and the hub hands each whole frame one connection
sends to every other connection, as a bus delivers a frame to every other node.

    async with CanTcpHub(port=5010) as hub:   # hub.url = "socket://127.0.0.1:5010"
        ...

A frame of python-can's serial interface: 0xAA, timestamp (u32 LE, ms), DLC
(u8, 0..8), identifier (u32 LE, flags in bits 29..31), DLC data bytes, 0xBB.
Bytes that do not form such a frame are skipped up to the next 0xAA.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging

log = logging.getLogger(__name__)

START, END = 0xAA, 0xBB
HEADER = 10  # start, timestamp, DLC, identifier
MAX_DLC = 8
#: a connection whose unsent frames exceed this many bytes gets no more (it does not read)
MAX_BACKLOG = 1 << 20


def split_frames(buf: bytearray) -> list[bytes]:
    """Remove and return the whole frames at the front of ``buf``; junk before a
    frame is dropped, an incomplete frame stays in ``buf``."""
    frames = []
    while buf:
        start = buf.find(START)
        if start < 0:
            buf.clear()
            break
        del buf[:start]
        if len(buf) < HEADER:
            break
        dlc = buf[5]
        size = HEADER + dlc + 1
        if dlc > MAX_DLC:
            del buf[:1]
            continue
        if len(buf) < size:
            break
        if buf[size - 1] != END:
            del buf[:1]
            continue
        frames.append(bytes(buf[:size]))
        del buf[:size]
    return frames


class CanTcpHub:
    """TCP server relaying serial-framed CAN frames between its connections."""

    def __init__(self, *, host: str = "127.0.0.1", port: int = 0):
        self.host, self.port = host, port
        self.url = ""
        self.frames_relayed = 0
        self._server: asyncio.Server | None = None
        self._writers: set[asyncio.StreamWriter] = set()
        self._connections: set[asyncio.Task] = set()  # one per connected node, ended by aclose

    async def __aenter__(self) -> CanTcpHub:
        self._server = await asyncio.start_server(self._serve, self.host, self.port)
        self.port = self._server.sockets[0].getsockname()[1]
        self.url = f"socket://{self.host}:{self.port}"
        return self

    async def __aexit__(self, *exc) -> None:
        await self.aclose()

    async def aclose(self) -> None:
        """Close the server and every connection, and wait for their handlers (idempotent)."""
        if self._server is not None:
            self._server.close()
            self._server = None
        for w in list(self._writers):
            w.close()
        self._writers.clear()
        if self._connections:  # each sees its end of file and returns: none is left to be cancelled
            await asyncio.wait(list(self._connections), timeout=1.0)

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        assert task is not None  # a connection's handler runs as a task
        self._connections.add(task)
        self._writers.add(writer)
        buf = bytearray()
        try:
            while data := await reader.read(4096):
                buf += data
                for frame in split_frames(buf):
                    self._relay(frame, writer)
        except (ConnectionError, OSError) as err:
            log.debug("CAN hub connection lost: %s", err)
        finally:
            self._connections.discard(task)
            self._writers.discard(writer)
            writer.close()
            with contextlib.suppress(Exception):
                await writer.wait_closed()

    def _relay(self, frame: bytes, sender: asyncio.StreamWriter) -> None:
        for w in self._writers:
            if w is not sender and not w.is_closing() and w.transport.get_write_buffer_size() < MAX_BACKLOG:
                w.write(frame)
        self.frames_relayed += 1
