"""A real Modbus TCP gateway in front of the simulator's drives, whose serial drop to some of them
can break: every request is forwarded and answered as it comes, except those to a device id in
`broken`, which reach nothing (that drive gets no request: its comm-loss watchdog runs out) and
which the gateway answers itself, after `ANSWER_S`, with exception 0B (gateway target device
failed to respond), as a TCP-to-RS-485 gateway does (drives/stop.py: PASSING_EXCEPTIONS)."""

from __future__ import annotations

import asyncio
import contextlib

#: wall s the gateway waits for a drive on a broken drop before it answers 0B itself
ANSWER_S = 0.02
TARGET_FAILED = 0x0B


class Gateway:
    """Listens on 127.0.0.1 (any free port) for clients of the Modbus TCP server at `port`."""

    def __init__(self, port: int):
        self.port = port
        self.broken: set[int] = set()  # device ids whose drop is broken
        self._server: asyncio.Server | None = None
        self._tasks: set[asyncio.Task[None]] = set()

    async def start(self) -> str:
        """Start listening; the URL for the client."""
        self._server = await asyncio.start_server(self._serve, "127.0.0.1", 0)
        return f"tcp://127.0.0.1:{self._server.sockets[0].getsockname()[1]}"

    async def aclose(self) -> None:
        if self._server is not None:
            self._server.close()
        for task in self._tasks:
            task.cancel()
        await asyncio.gather(*self._tasks, return_exceptions=True)

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        assert task is not None
        self._tasks.add(task)
        up_reader, up_writer = await asyncio.open_connection("127.0.0.1", self.port)
        try:
            with contextlib.suppress(ConnectionError, asyncio.IncompleteReadError):
                while True:  # one request at a time, as a serial drop takes them
                    request = await _frame(reader)
                    if request[6] in self.broken:
                        await asyncio.sleep(ANSWER_S)
                        writer.write(_exception(request, TARGET_FAILED))
                    else:
                        up_writer.write(request)
                        await up_writer.drain()
                        writer.write(await _frame(up_reader))
                    await writer.drain()
        finally:
            self._tasks.discard(task)
            writer.close()
            up_writer.close()


async def _frame(reader: asyncio.StreamReader) -> bytes:
    """One Modbus TCP frame (MBAP header + unit id + PDU)."""
    head = await reader.readexactly(6)
    return head + await reader.readexactly(int.from_bytes(head[4:6], "big"))


def _exception(request: bytes, code: int) -> bytes:
    """The exception answer `code` to `request`: its transaction and unit id, its function | 0x80."""
    return request[:4] + (3).to_bytes(2, "big") + bytes([request[6], request[7] | 0x80, code])
