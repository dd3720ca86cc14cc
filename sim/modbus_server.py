"""Modbus servers for the emulated drives: TCP on loopback and RTU over a pty.

Both serve a dict {device id: DriveModel} ({1: spin, 2: orbit}) on ONE
network. TCP is pymodbus 3.16's server. The datastore is pymodbus' `SimDevice`
(the successor of the deprecated ModbusServerContext / ModbusDeviceContext /
ModbusSequentialDataBlock): each drive is a SimDevice whose whole address
space is declared and whose `action` hook routes every request live to
`DriveModel.read` / `DriveModel.write`, so the model alone decides the map and
its exception codes (02 unknown / read-only address, 03 bad value or
parameter write while running). Function codes other than 03, 06 and 16
answer exception 01.

Every received request passes a gate (pymodbus' `trace_pdu` hook on TCP)
before it is executed:
- a request addressed to a drive feeds that drive's watchdog
  (`note_request`), also when it will be answered with an exception;
- a request for an unknown device id is not answered on RTU (as on a real
  RS-485 line: the client times out); on TCP it is answered with exception
  0x0B (gateway target device failed to respond), as a TCP/RTU gateway does;
- `set_unresponsive(True)` drops every request (a dead link: the client times
  out, and since the drives receive nothing their watchdogs run down).

The watchdog judges a request by when it arrived, not by when this loop got round
to it: each server ticks its drives' AwakeClocks (sim/clock.py) every `AWAKE_TICK`
s, so a stall of the loop (a starved process, a blocked loop) while requests wait
in the socket or the pty does not count as the master's silence.

RTU over a pty: a server of our own works the master end of one pty
(sim/pty.py); clients open the slave (`endpoint.path`: pymodbus, pyserial,
mbpoll). The endpoint keeps the slave open and raw, so clients may open and
close the path repeatedly. The baud rate is only carried in the URL (a pty has
no line timing). It is not pymodbus' ModbusSerialServer, which loses requests
that arrive back to back: its RTU framer (FramerRTU.decode) consumes the whole
receive buffer with the first frame, so a second frame read in the same chunk
is dropped unanswered; and its ServerRequestHandler keeps ONE `last_pdu` that
the next chunk overwrites (or clears) before the deferred handler runs, so
the first request is lost and the second answered twice. This server answers
every well-formed request exactly once, in order (`find_request` in
sim/rtu_frames.py frames by function-code size and CRC, hunting byte by byte
past noise).
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import logging
import os
import struct
from collections.abc import Mapping
from typing import cast

from pymodbus.constants import ExcCodes
from pymodbus.framer import FramerType
from pymodbus.pdu import ModbusPDU
from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from .drive_model import DriveModel
from .drive_registers import DriveModbusException
from .pty import close_fds, open_raw_pty
from .rtu_frames import MAX_ADU, crc16, find_request, with_crc

log = logging.getLogger(__name__)

# crc16 and find_request (sim/rtu_frames.py) stay importable from here
__all__ = ["ModbusEndpoint", "crc16", "find_request", "serve_modbus_rtu_pty", "serve_modbus_tcp"]

_SUPPORTED_FUNCTIONS = (3, 6, 16)

AWAKE_TICK = 0.01  # s between two ticks of the drives' AwakeClocks (their grace is 0.1 s)


async def _drive_action(
    drive: DriveModel,
    function_code: int,
    start_address: int,
    address: int,
    count: int,
    registers: list[int],
    set_values: list[int] | list[bool] | None,
) -> ExcCodes | None:
    """SimDevice action: apply one request to the drive model, live."""
    if function_code not in _SUPPORTED_FUNCTIONS:
        return ExcCodes.ILLEGAL_FUNCTION
    try:
        if set_values is None:  # read (also the echo read after a 06 write)
            offset = address - start_address
            registers[offset : offset + count] = drive.read(address, count)
        else:
            drive.write(address, [int(v) for v in set_values])
    except DriveModbusException as exc:
        return ExcCodes(exc.code)
    return None


async def _gateway_no_response(*_args) -> ExcCodes:
    """Catch-all device (TCP): an unknown unit id behind the gateway."""
    return ExcCodes.GATEWAY_NO_RESPONSE


def _sim_devices(drives: Mapping[int, DriveModel], catch_all: bool) -> list[SimDevice]:
    def whole_space() -> list[SimData]:
        return [SimData(address=0, count=0x10000, datatype=DataType.REGISTERS)]

    devices = []
    for dev_id, drive in drives.items():
        if not 1 <= dev_id <= 247:
            raise ValueError(f"device id {dev_id} outside 1..247")
        devices.append(
            SimDevice(
                id=dev_id,
                simdata=whole_space(),
                action=functools.partial(_drive_action, drive),
            )
        )
    if catch_all:
        devices.append(SimDevice(id=0, simdata=whole_space(), action=_gateway_no_response))
    return devices


class _Gate:
    """Every received request: watchdog feeding, unknown device ids, unresponsive mode.

    `trace_pdu` is the pymodbus hook (TCP); `admit` is the same rule for the RTU server.
    """

    def __init__(self, drives: Mapping[int, DriveModel], answer_unknown: bool) -> None:
        self.drives = dict(drives)
        self.answer_unknown = answer_unknown
        self.unresponsive = False
        self.to_drop = 0  # the next requests dropped unanswered (late answers)

    def admit(self, dev_id: int) -> bool:
        """Whether a request for `dev_id` is executed and answered (feeds its watchdog)."""
        if self.unresponsive:
            return False  # dropped: no response
        if self.to_drop > 0:
            self.to_drop -= 1
            return False
        drive = self.drives.get(dev_id)
        if drive is None:
            return self.answer_unknown
        drive.note_request()
        return True

    def trace_pdu(self, sending: bool, pdu: ModbusPDU) -> ModbusPDU | None:
        if sending:
            return pdu
        return pdu if self.admit(pdu.dev_id) else None


async def _tick_awake(drives: Mapping[int, DriveModel]) -> None:
    """Tick the served drives' AwakeClocks while this loop runs; unwatched when cancelled."""
    clocks = list({id(d.awake): d.awake for d in drives.values() if d.awake is not None}.values())
    if not clocks:  # drives on plain wall time: nothing to tick
        return
    try:
        while True:
            for clock in clocks:
                clock.tick()
            await asyncio.sleep(AWAKE_TICK)
    finally:
        for clock in clocks:
            clock.unwatched()


class ModbusEndpoint:
    """A running Modbus server for the drives.

    url: "tcp://127.0.0.1:P" or "rtu:///dev/pts/N?baud=19200";
    port: TCP port (None for RTU); path: the client's pty (None for TCP).
    """

    def __init__(
        self,
        *,
        url: str,
        port: int | None,
        path: str | None,
        server: ModbusTcpServer | _RtuPtyServer,
        gate: _Gate,
    ) -> None:
        self.url = url
        self.port = port
        self.path = path
        self._server = server
        self._gate = gate
        self._closed = False
        self._ticker = asyncio.get_running_loop().create_task(_tick_awake(gate.drives), name="sim-drives-awake")

    def set_unresponsive(self, on: bool) -> None:
        """Fault injection: while on, requests are dropped and time out."""
        self._gate.unresponsive = bool(on)

    def drop_next(self, n: int = 1) -> None:
        """Fault injection: the next `n` requests go unanswered (each times out once)."""
        self._gate.to_drop = int(n)

    @property
    def unresponsive(self) -> bool:
        return self._gate.unresponsive

    @property
    def requests_to_drop(self) -> int:
        """How many of the next requests still go unanswered (drop_next's count, as the server drops them)."""
        return self._gate.to_drop

    async def aclose(self) -> None:
        """Stop serving and release the socket / ptys. Idempotent."""
        if self._closed:
            return
        self._closed = True
        self._ticker.cancel()
        await asyncio.wait([self._ticker])  # its clocks unwatched
        listener = getattr(self._server, "transport", None)
        await self._server.shutdown()
        if isinstance(listener, asyncio.AbstractServer):
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(listener.wait_closed(), timeout=1.0)

    async def __aenter__(self) -> ModbusEndpoint:
        return self

    async def __aexit__(self, *exc_info) -> None:
        await self.aclose()

    def __repr__(self) -> str:
        return f"ModbusEndpoint({self.url!r})"


async def serve_modbus_tcp(drives: Mapping[int, DriveModel], host: str = "127.0.0.1", port: int = 0) -> ModbusEndpoint:
    """Serve `drives` ({device id: model}) as Modbus TCP on host:port (0 = any free port)."""
    gate = _Gate(drives, answer_unknown=True)
    server = ModbusTcpServer(
        _sim_devices(drives, catch_all=True),
        framer=FramerType.SOCKET,
        address=(host, port),
        # pymodbus types trace_pdu as returning a PDU, yet drops the request on None (its transaction.py)
        trace_pdu=gate.trace_pdu,  # type: ignore[arg-type]
    )
    await server.serve_forever(background=True)
    bound = cast(asyncio.Server, server.transport).sockets[0].getsockname()[1]
    return ModbusEndpoint(url=f"tcp://{host}:{bound}", port=bound, path=None, server=server, gate=gate)


# ------------------------------------------------------------------ RTU
class _RtuPtyServer:
    """Modbus RTU server on the master end of a pty: every well-formed request
    is executed and answered exactly once, in the order received.

    Frames are delimited by function-code size and CRC (a pty carries no line
    timing); several frames in one read are all served. A request is handled
    synchronously in the read callback (the drive models are synchronous), so
    no later request can overtake or replace it. Answers are queued to the
    master; what a client never reads is forgotten when it reopens the line.
    """

    def __init__(self, drives: Mapping[int, DriveModel], gate: _Gate) -> None:
        self._loop = asyncio.get_running_loop()
        self._drives = dict(drives)
        self._gate = gate
        master, slave, self.path = open_raw_pty()
        self.master: int | None = master  # None once shut down
        self._slave: int | None = slave
        self._rx = bytearray()
        self._tx = bytearray()
        self._writing = False
        self.requests = 0  # well-formed requests received
        self.answered = 0
        self.noise_bytes = 0  # bytes dropped while hunting for a frame
        self._loop.add_reader(master, self._on_readable)

    # -- bytes ----------------------------------------------------------------
    def _on_readable(self) -> None:
        if self.master is None:  # shut down (the reader is removed before the master is cleared)
            return
        try:
            data = os.read(self.master, 4096)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:  # EIO: no slave open (cannot happen while we hold one)
            return
        self._rx += data
        while True:
            found = find_request(self._rx)
            if found is None:
                break
            start, end = found
            if start:
                self.noise_bytes += start
                log.debug("RTU: %d byte(s) of noise before a frame dropped", start)
            frame = bytes(self._rx[start:end])
            del self._rx[:end]
            self._serve(frame)
        if len(self._rx) > 2 * MAX_ADU:  # no frame in it: noise
            self.noise_bytes += len(self._rx) - MAX_ADU
            del self._rx[:-MAX_ADU]

    def _send(self, adu: bytes) -> None:
        self._tx += adu
        self.answered += 1
        if not self._writing:
            self._flush()

    def _flush(self) -> None:
        master = self.master
        if master is None:  # shut down: nothing more goes out
            return
        try:
            n = os.write(master, self._tx)
        except (BlockingIOError, InterruptedError):
            n = 0
        except OSError:
            self._tx.clear()
            n = 0
        del self._tx[:n]
        if self._tx and not self._writing:
            self._writing = True
            self._loop.add_writer(master, self._on_writable)
        elif not self._tx and self._writing:
            self._writing = False
            self._loop.remove_writer(master)

    def _on_writable(self) -> None:
        self._flush()

    # -- requests ---------------------------------------------------------------
    def _serve(self, frame: bytes) -> None:
        dev, fc, data = frame[0], frame[1], frame[2:-2]
        self.requests += 1
        if dev == 0 or not self._gate.admit(dev):
            return  # broadcast (nothing to answer), unknown id or a dead line: silence
        drive = self._drives[dev]
        try:
            body = self._execute(drive, fc, data)
        except DriveModbusException as exc:
            body = bytes([fc | 0x80, exc.code])
        self._send(with_crc(bytes([dev]) + body))

    @staticmethod
    def _execute(drive: DriveModel, fc: int, data: bytes) -> bytes:
        """The response PDU (function code onward) for one request PDU."""
        if fc not in _SUPPORTED_FUNCTIONS:
            raise DriveModbusException(int(ExcCodes.ILLEGAL_FUNCTION), f"function code {fc}")
        address, count = struct.unpack(">HH", data[:4])
        if fc == 3:
            if not 1 <= count <= 125:
                raise DriveModbusException(int(ExcCodes.ILLEGAL_VALUE), f"count {count}")
            words = drive.read(address, count)
            return struct.pack(f">BB{count}H", fc, 2 * count, *words)
        if fc == 6:
            drive.write(address, [count])  # the second word is the value
            return bytes([fc]) + data[:4]
        byte_count, values = data[4], data[5:]
        if not 1 <= count <= 123 or byte_count != 2 * count or len(values) != byte_count:
            raise DriveModbusException(int(ExcCodes.ILLEGAL_VALUE), f"count {count}")
        drive.write(address, list(struct.unpack(f">{count}H", values)))
        return bytes([fc]) + data[:4]

    async def shutdown(self) -> None:
        if self.master is None:
            return
        self._loop.remove_reader(self.master)
        if self._writing:
            self._loop.remove_writer(self.master)
        close_fds(self.master, self._slave)
        self.master = self._slave = None


async def serve_modbus_rtu_pty(drives: Mapping[int, DriveModel], baud: int = 19200) -> ModbusEndpoint:
    """Serve `drives` as Modbus RTU on a pty; the client opens `endpoint.path`.

    The baud rate is only carried in the URL (a pty has no line timing).
    """
    for dev_id in drives:
        if not 1 <= dev_id <= 247:
            raise ValueError(f"device id {dev_id} outside 1..247")
    gate = _Gate(drives, answer_unknown=False)
    server = _RtuPtyServer(drives, gate)
    return ModbusEndpoint(
        url=f"rtu://{server.path}?baud={baud}",
        port=None,
        path=server.path,
        server=server,
        gate=gate,
    )
