"""Non-blocking byte links to the A/D board, chosen by pyserial-style URL.

``socket://host:port``  a TCP serial device server (a non-blocking socket)
``/dev/ttyUSB0``, a pty  a serial port opened by pyserial (raw mode, non-blocking),
                         optionally ``/dev/ttyUSB0?baud=921600`` (default 115200;
                         a pty ignores it)

Both are read the same way: the file descriptor is watched with
``loop.add_reader`` and every readable event hands the bytes to ``on_data`` in
the event loop, so nothing blocks and no thread is needed. End of stream, a
reset connection or a hung-up line calls ``on_lost`` once.
"""

from __future__ import annotations

import asyncio
import functools
import os
import socket
import termios
from collections.abc import Callable
from urllib.parse import parse_qs, urlsplit

from daq.errors import DaqLinkError

READ_SIZE = 1 << 18
_RCVBUF = 1 << 22


class ByteLink:
    """An open, non-blocking byte source on the running loop."""

    def __init__(
        self,
        url: str,
        fd: int,
        recv: Callable[[int], bytes],
        closer: Callable[[], None],
        on_data: Callable[[bytes], None],
        on_lost: Callable[[Exception], None],
    ) -> None:
        self.url = url
        self._fd = fd
        self._recv = recv
        self._closer = closer
        self._on_data = on_data
        self._on_lost = on_lost
        self._loop = asyncio.get_running_loop()
        self.closed = False
        self.bytes_read = 0
        self._loop.add_reader(fd, self._readable)

    def _readable(self) -> None:
        try:
            data = self._recv(READ_SIZE)
        except (BlockingIOError, InterruptedError):
            return
        except OSError as err:  # EIO: hung-up pty; ECONNRESET ...
            self._lost(DaqLinkError(f"{self.url}: link lost ({err})"))
            return
        if not data:
            self._lost(DaqLinkError(f"{self.url}: link closed by the other end"))
            return
        self.bytes_read += len(data)
        self._on_data(data)

    def read_ready(self, limit: int = 1 << 24) -> bytes:
        """What can be read right now without waiting (at most ``limit`` bytes).
        Does not call ``on_data``; a lost link is reported through ``on_lost``."""
        parts, n = [], 0
        while n < limit and not self.closed:
            try:
                data = self._recv(READ_SIZE)
            except (BlockingIOError, InterruptedError):
                break
            except OSError as err:
                self._lost(DaqLinkError(f"{self.url}: link lost ({err})"))
                break
            if not data:
                self._lost(DaqLinkError(f"{self.url}: link closed by the other end"))
                break
            parts.append(data)
            n += len(data)
        self.bytes_read += n
        return b"".join(parts)

    def _lost(self, err: Exception) -> None:
        if self.closed:
            return
        self.close()
        self._on_lost(err)

    def close(self) -> None:
        """Idempotent."""
        if self.closed:
            return
        self.closed = True
        self._loop.remove_reader(self._fd)
        try:
            self._closer()
        except OSError:
            pass


async def open_link(
    url: str, on_data: Callable[[bytes], None], on_lost: Callable[[Exception], None], *, timeout: float = 5.0
) -> ByteLink:
    """Open ``url`` (see module doc); raises DaqLinkError naming the URL if it cannot."""
    if url.startswith("socket://"):
        return await _open_socket(url, on_data, on_lost, timeout)
    if url.startswith("tcp://"):
        raise DaqLinkError(
            f"{url}: the A/D board takes pyserial URLs; for a TCP serial device server "
            f"write socket://{url.removeprefix('tcp://')} (tcp:// is the Modbus drives' URL)"
        )
    if "://" in url:
        raise DaqLinkError(f"{url}: unsupported URL (use socket://host:port or a device path)")
    return _open_serial(url, on_data, on_lost)


async def _open_socket(
    url: str, on_data: Callable[[bytes], None], on_lost: Callable[[Exception], None], timeout: float
) -> ByteLink:
    parts = urlsplit(url)
    try:
        host, port = parts.hostname, parts.port
    except ValueError as err:
        raise DaqLinkError(f"{url}: bad port ({err})") from err
    if not host or port is None:
        raise DaqLinkError(f"{url}: expected socket://host:port")
    loop = asyncio.get_running_loop()
    try:
        infos = await loop.getaddrinfo(host, port, type=socket.SOCK_STREAM)
        family, _, _, _, addr = infos[0]
        sock = socket.socket(family, socket.SOCK_STREAM)
    except OSError as err:
        raise DaqLinkError(f"{url}: cannot resolve or create socket ({err})") from err
    try:
        sock.setblocking(False)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, _RCVBUF)
        async with asyncio.timeout(timeout):  # not wait_for: in 3.11 it drops a cancel arriving as it ends
            await loop.sock_connect(sock, addr)
    except OSError as err:  # TimeoutError included
        sock.close()
        raise DaqLinkError(f"{url}: cannot connect ({_why(err, timeout)})") from err
    return ByteLink(url, sock.fileno(), sock.recv, sock.close, on_data, on_lost)


def _open_serial(url: str, on_data: Callable[[bytes], None], on_lost: Callable[[Exception], None]) -> ByteLink:
    import serial  # pyserial: only serial ports need it

    path, _, query = url.partition("?")
    try:
        baud = int(parse_qs(query).get("baud", ["115200"])[0])
    except ValueError as err:
        raise DaqLinkError(f"{url}: bad baud rate") from err
    try:
        # docs/protocols/adc-frames.md: "No flow control" (no XON/XOFF, no RTS/CTS, no DSR/DTR)
        port = serial.Serial(path, baudrate=baud, timeout=0, xonxoff=False, rtscts=False, dsrdtr=False)
    except (serial.SerialException, OSError, ValueError) as err:
        raise DaqLinkError(f"{url}: cannot open serial port ({err})") from err
    fd = port.fileno()
    os.set_blocking(fd, False)
    # pyserial leaves VMIN = 0, where an empty read means "nothing yet"; with VMIN = 1
    # a non-blocking read without data raises EAGAIN and b"" means a hang-up, as on a socket
    attrs = termios.tcgetattr(fd)
    attrs[6][termios.VMIN], attrs[6][termios.VTIME] = 1, 0
    termios.tcsetattr(fd, termios.TCSANOW, attrs)
    return ByteLink(url, fd, functools.partial(os.read, fd), port.close, on_data, on_lost)


def _why(err: OSError, timeout: float) -> str:
    """A failed connect's cause in words (`timeout`: s it was given)."""
    if isinstance(err, TimeoutError):
        return f"no answer to the connection within {timeout:g} s: a wrong or unreachable host, or a firewall dropping the port"
    if isinstance(err, ConnectionRefusedError):
        return "connection refused: nothing listens on that port"
    return str(err)
