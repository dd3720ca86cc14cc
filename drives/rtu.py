"""Modbus RTU master on a serial device: one exchange at a time, in order.

    line = RtuLine("/dev/ttyUSB0", baud=19200, timeout=0.3)
    await line.connect()
    rsp = await line.read_holding_registers(0, count=7, device_id=1)   # RtuAnswer

Used by `ModbusLink` for `rtu://` URLs (TCP stays on pymodbus' client).
pymodbus' serial client is not used because RTU has no transaction id and
its framer cannot tell a late answer from the awaited one: it takes the
first frame with the right device id, and drops the rest of a read that
held two frames. Here:
- before every request the line must have been silent for the RTU
  inter-frame time t3.5 (3.5 characters of 11 bits; 1.75 ms above 19200
  baud, as the Modbus serial line spec fixes it), and longer after a failed
  exchange (`settle`), so that a late answer lands before the next request,
  where it is discarded;
- an answer is accepted only if it is CRC-valid, from the addressed device,
  with the request's function code (or its exception) and the request's shape
  (FC03: byte count = 2 x count; FC06: echo of address and value; FC16: echo
  of address and quantity); anything else on the line is dropped and counted
  (`discarded_frames`, `noise_bytes`), and the wait for the real answer goes on.
A stale answer identical in shape to the awaited one (same device, function
and size) can only be excluded by timing: after a failed exchange the next
request waits until the line has been quiet for `settle` s (default
min(timeout, 0.05 s): no longer than a poll interval) counted from the failure, so an answer up to
timeout + settle late is discarded; a later one cannot be told apart on RTU.
"""

from __future__ import annotations

import asyncio
import logging
import os
import struct
import termios
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

log = logging.getLogger(__name__)

_MAX_ADU = 256


def _crc_table() -> list[int]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
        table.append(crc)
    return table


_CRC_TABLE = _crc_table()


def crc16(data: bytes | bytearray) -> int:
    """Modbus CRC-16 (reflected 0xA001, init 0xFFFF); on the wire low byte first."""
    crc = 0xFFFF
    for b in data:
        crc = (crc >> 8) ^ _CRC_TABLE[(crc ^ b) & 0xFF]
    return crc


def frame(device_id: int, pdu: bytes) -> bytes:
    """RTU ADU: device id, PDU, CRC."""
    body = bytes([device_id]) + pdu
    return body + crc16(body).to_bytes(2, "little")


def inter_frame_silence(baud: int) -> float:
    """t3.5 in s: 3.5 characters of 11 bits; fixed 1.75 ms above 19200 baud."""
    return 1.75e-3 if baud > 19200 else 3.5 * 11.0 / baud


def _response_size(buf: bytes | bytearray, k: int) -> int | None:
    """Size of a response frame starting at buf[k] (0: unknown layout; None: need more)."""
    fc = buf[k + 1]
    if fc & 0x80:
        return 5
    if fc in (1, 2, 3, 4, 23):
        return None if k + 2 >= len(buf) else buf[k + 2] + 5
    if fc in (5, 6, 15, 16):
        return 8
    return 0


def next_frame(buf: bytes | bytearray) -> tuple[int, int] | None:
    """(start, end) of the first complete CRC-valid response frame in `buf`, or None.

    Bytes before `start` are noise. An incomplete frame at the head does not
    hide a complete one behind it (the head was a fragment).
    """
    n = len(buf)
    for k in range(n - 4):
        size = _response_size(buf, k)
        if not size or k + size > n:
            continue
        end = k + size
        if crc16(buf[k : end - 2]) == buf[end - 2] | buf[end - 1] << 8:
            return k, end
    return None


@dataclass
class RtuAnswer:
    """An accepted answer; quacks like the pymodbus response the link expects."""

    dev_id: int
    function_code: int
    registers: list[int] = field(default_factory=list)
    exception_code: int = 0

    def isError(self) -> bool:  # pymodbus name
        return self.function_code >= 0x80


@dataclass
class _Pending:
    device_id: int
    function_code: int
    request: bytes  # the request PDU after the function code
    future: asyncio.Future[RtuAnswer]


class RtuGarbled(TimeoutError):
    """No valid answer within the timeout although bytes came on the line: another device on the
    port, or the drives at another baud rate or parity (the message says how many bytes)."""


class RtuLine:
    """An RTU master on `path` (8N1 at `baud`), `timeout` s per answer.

    Methods mirror the pymodbus client calls ModbusLink makes; errors are
    OSError (line failure) and asyncio.TimeoutError (no valid answer; RtuGarbled when bytes came).
    """

    def __init__(self, path: str, *, baud: int = 19200, timeout: float = 1.0, settle: float | None = None):
        self.path = path
        self.baud = int(baud)
        self.timeout = float(timeout)
        self.silence = inter_frame_silence(self.baud)
        # quiet time required after a failed exchange: long enough for a late answer to land
        self.settle = float(settle) if settle is not None else min(self.timeout, 0.05)
        self._port = None
        self._fd: int | None = None
        self._rx = bytearray()
        self._last_activity = 0.0  # monotonic end of the last byte seen or sent
        self._dirty = False  # the last exchange failed: settle before the next
        self._pending: _Pending | None = None
        self._lock = asyncio.Lock()
        self.discarded_frames = 0  # valid frames that were not the awaited answer
        self.noise_bytes = 0
        self.bytes_in = 0  # every byte read from the line

    # -- connection -----------------------------------------------------------
    @property
    def connected(self) -> bool:
        return self._fd is not None

    async def connect(self) -> bool:
        import serial  # pyserial: opens and configures the port (8N1, baud, exclusive)

        try:
            port = serial.Serial(
                self.path,
                baudrate=self.baud,
                bytesize=8,
                parity="N",
                stopbits=1,
                timeout=0,
                exclusive=True,
            )
        except (serial.SerialException, ValueError) as err:
            raise OSError(f"cannot open {self.path}: {err}") from err
        fd = port.fileno()
        try:
            attrs = termios.tcgetattr(fd)
            attrs[6][termios.VMIN], attrs[6][termios.VTIME] = 1, 0  # an empty read is a hang-up
            termios.tcsetattr(fd, termios.TCSANOW, attrs)
            termios.tcflush(fd, termios.TCIFLUSH)
        except termios.error as err:  # not an OSError: a link error like the open's
            port.close()  # opened exclusive: left open, every later connect would fail
            raise OSError(f"cannot set up {self.path}: {err}") from err
        except BaseException:
            port.close()
            raise
        self._port, self._fd = port, fd
        self._rx.clear()
        self._last_activity = time.monotonic()
        asyncio.get_running_loop().add_reader(fd, self._on_readable)
        return True

    def close(self) -> None:
        if self._fd is not None:
            asyncio.get_running_loop().remove_reader(self._fd)
            self._fd = None
        if self._port is not None:
            port, self._port = self._port, None
            try:
                port.close()
            except OSError:
                pass
        self._fail_pending(ConnectionError(f"{self.path} closed"))

    # -- requests ---------------------------------------------------------------
    async def read_holding_registers(self, address: int, *, count: int, device_id: int) -> RtuAnswer:
        return await self._exchange(device_id, 3, struct.pack(">HH", address, count))

    async def write_register(self, address: int, value: int, *, device_id: int) -> RtuAnswer:
        return await self._exchange(device_id, 6, struct.pack(">HH", address, value))

    async def write_registers(self, address: int, values: Sequence[int], *, device_id: int) -> RtuAnswer:
        n = len(values)
        return await self._exchange(device_id, 16, struct.pack(f">HHB{n}H", address, n, 2 * n, *values))

    async def _exchange(self, device_id: int, fc: int, request: bytes) -> RtuAnswer:
        async with self._lock:
            if self._fd is None:
                raise ConnectionError(f"{self.path} is not open")
            heard, frames = self.bytes_in, self.discarded_frames
            # a line never quiet (another device streaming) fails like one that does not answer; a
            # late answer lands up to timeout + settle after a failure, then settle of quiet follows
            try:
                async with asyncio.timeout(self.timeout + 2 * self.settle):
                    await self._wait_silence()
            except TimeoutError:
                raise RtuGarbled(self._garbled(self.bytes_in - heard, self.discarded_frames - frames)) from None
            self._drop_input("before a request")
            adu = frame(device_id, bytes([fc]) + request)
            fut: asyncio.Future[RtuAnswer] = asyncio.get_running_loop().create_future()
            self._pending = _Pending(device_id, fc, request, fut)
            self._dirty = True  # cleared by an accepted answer
            try:
                self._write(adu)
                async with asyncio.timeout(self.timeout):  # (3.11's wait_for can lose a cancellation)
                    return await fut
            except TimeoutError:
                if self.bytes_in > heard:  # bytes came, no answer of them
                    raise RtuGarbled(self._garbled(self.bytes_in - heard, self.discarded_frames - frames)) from None
                raise
            finally:
                self._pending = None
                if self._dirty:  # failed: the settle time runs from now
                    self._last_activity = max(self._last_activity, time.monotonic())

    def _garbled(self, came: int, frames: int) -> str:
        """Bytes that came during an exchange without its answer, in words, with what to check:
        valid frames among them are a drive answering late or another master, never a wrong baud rate."""
        if frames:
            return (
                f"{came} byte(s) came on {self.path}, {frames} valid RTU frame(s) among them, none this "
                "request's answer: a drive answering later than the timeout (a late answer is dropped), or "
                "another Modbus master on the line?"
            )
        return (
            f"{came} byte(s) came on {self.path}, no valid RTU frame (CRC) among them: is another device on this "
            f"port (the A/D board's stream?), or are the drives at another baud rate or parity than {self.baud} "
            "baud, 8N1 (?baud= in the URL)?"
        )

    async def _wait_silence(self) -> None:
        """Until the line has been quiet for t3.5 (after a failure: `settle`)."""
        while True:
            quiet = self.settle if self._dirty else self.silence
            wait = self._last_activity + quiet - time.monotonic()
            if wait <= 0:
                return
            await asyncio.sleep(wait)

    def _write(self, adu: bytes) -> None:
        if self._fd is None:
            raise ConnectionError(f"{self.path} is not open")
        try:
            n = os.write(self._fd, adu)
        except (BlockingIOError, InterruptedError):
            n = 0
        if n != len(adu):  # a serial driver takes a whole small frame or nothing
            raise OSError(f"{self.path}: wrote {n} of {len(adu)} bytes")
        # (a UART is still shifting it out; the answer, later still, restarts the silence)
        self._last_activity = time.monotonic()

    def _drop_input(self, when: str) -> None:
        if self._rx:
            self.noise_bytes += len(self._rx)
            log.warning("%s: %d stale byte(s) dropped %s", self.path, len(self._rx), when)
            self._rx.clear()

    # -- receiving --------------------------------------------------------------
    def _on_readable(self) -> None:
        if self._fd is None:  # closed while the callback was queued
            return
        try:
            data = os.read(self._fd, 4096)
        except (BlockingIOError, InterruptedError):
            return
        except OSError as err:
            self.close()
            self._fail_pending(err)
            return
        if not data:  # VMIN = 1: readable with nothing to read is a hang-up
            self.close()
            self._fail_pending(ConnectionError(f"{self.path} hung up"))
            return
        self._last_activity = max(self._last_activity, time.monotonic())
        self.bytes_in += len(data)
        self._rx += data
        self._match()

    def _match(self) -> None:
        p = self._pending
        while (found := next_frame(self._rx)) is not None:
            start, end = found
            adu = bytes(self._rx[start:end])
            del self._rx[:end]
            if start:
                self.noise_bytes += start
            answer = self._accept(p, adu) if p is not None and not p.future.done() else None
            if answer is not None and p is not None:
                self._dirty = False
                p.future.set_result(answer)
                if self._rx:
                    self._drop_input("after an answer")
                return
            self.discarded_frames += 1
            log.warning("%s: discarded a frame that is not the awaited answer: %s", self.path, adu.hex(" "))
        if len(self._rx) > 2 * _MAX_ADU:
            self.noise_bytes += len(self._rx) - _MAX_ADU
            del self._rx[:-_MAX_ADU]

    @staticmethod
    def _accept(p: _Pending, adu: bytes) -> RtuAnswer | None:
        """The answer to `p` if `adu` is one (device, function, shape), else None."""
        dev, fc, body = adu[0], adu[1], adu[2:-2]
        if dev != p.device_id:
            return None
        if fc == p.function_code | 0x80:
            return RtuAnswer(dev, fc, exception_code=body[0])
        if fc != p.function_code:
            return None
        if fc == 3:
            count = struct.unpack(">H", p.request[2:4])[0]
            if body[0] != 2 * count:
                return None
            return RtuAnswer(dev, fc, list(struct.unpack(f">{count}H", body[1:])))
        if body != p.request[:4]:  # FC06: address + value; FC16: address + quantity
            return None
        return RtuAnswer(dev, fc)

    def _fail_pending(self, err: BaseException) -> None:
        p = self._pending
        if p is not None and not p.future.done():
            p.future.set_exception(err)
