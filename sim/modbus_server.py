"""Modbus servers for the emulated drives: TCP on loopback and RTU over a pty.

Both serve a dict {device id: DriveModel} ({1: spin, 2: orbit}) on ONE
network with pymodbus 3.16 servers. The datastore is pymodbus' `SimDevice`
(the successor of the deprecated ModbusServerContext / ModbusDeviceContext /
ModbusSequentialDataBlock): each drive is a SimDevice whose whole address
space is declared and whose `action` hook routes every request live to
`DriveModel.read` / `DriveModel.write`, so the model alone decides the map and
its exception codes (02 unknown / read-only address, 03 bad value or
parameter write while running). Function codes other than 03, 06 and 16
answer exception 01.

Every received request passes a gate (pymodbus' `trace_pdu` hook) before it
is executed:
- a request addressed to a drive feeds that drive's watchdog
  (`note_request`), also when it will be answered with an exception;
- a request for an unknown device id is not answered on RTU (as on a real
  RS-485 line: the client times out); on TCP it is answered with exception
  0x0B (gateway target device failed to respond), as a TCP/RTU gateway does;
- `set_unresponsive(True)` drops every request (a dead link: the client times
  out, and since the drives receive nothing their watchdogs run down).

RTU over a pty: two pseudo-terminals are created and their master ends are
bridged in-process (`loop.add_reader`), so the server opens one slave device
(`ModbusSerialServer`) and the client another (`endpoint.path`, any serial
client: pymodbus, pyserial, mbpoll). Both slave ends are kept open and raw by
the endpoint, so clients may open and close the path repeatedly. The baud
rate is only carried in the URL (a pty has no line timing).
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import os
import tty
from collections.abc import Mapping

from pymodbus.constants import ExcCodes
from pymodbus.framer import FramerType
from pymodbus.pdu import ModbusPDU
from pymodbus.server import ModbusSerialServer, ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from .drive_model import DriveModbusException, DriveModel

__all__ = ["ModbusEndpoint", "serve_modbus_rtu_pty", "serve_modbus_tcp"]

_SUPPORTED_FUNCTIONS = (3, 6, 16)


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
    """trace_pdu hook: watchdog feeding, unknown device ids, unresponsive mode."""

    def __init__(self, drives: Mapping[int, DriveModel], answer_unknown: bool) -> None:
        self.drives = dict(drives)
        self.answer_unknown = answer_unknown
        self.unresponsive = False

    def trace_pdu(self, sending: bool, pdu: ModbusPDU) -> ModbusPDU | None:
        if sending:
            return pdu
        if self.unresponsive:
            return None  # dropped: no response
        drive = self.drives.get(pdu.dev_id)
        if drive is None:
            return pdu if self.answer_unknown else None
        drive.note_request()
        return pdu


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
        server: ModbusTcpServer | ModbusSerialServer,
        gate: _Gate,
        bridge: _PtyBridge | None = None,
    ) -> None:
        self.url = url
        self.port = port
        self.path = path
        self._server = server
        self._gate = gate
        self._bridge = bridge
        self._closed = False

    def set_unresponsive(self, on: bool) -> None:
        """Fault injection: while on, requests are dropped and time out."""
        self._gate.unresponsive = bool(on)

    @property
    def unresponsive(self) -> bool:
        return self._gate.unresponsive

    async def aclose(self) -> None:
        """Stop serving and release the socket / ptys. Idempotent."""
        if self._closed:
            return
        self._closed = True
        listener = self._server.transport
        await self._server.shutdown()
        if isinstance(listener, asyncio.AbstractServer):
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(listener.wait_closed(), timeout=1.0)
        if self._bridge is not None:
            self._bridge.close()

    async def __aenter__(self) -> ModbusEndpoint:
        return self

    async def __aexit__(self, *exc_info) -> None:
        await self.aclose()

    def __repr__(self) -> str:
        return f"ModbusEndpoint({self.url!r})"


async def serve_modbus_tcp(
    drives: Mapping[int, DriveModel], host: str = "127.0.0.1", port: int = 0
) -> ModbusEndpoint:
    """Serve `drives` ({device id: model}) as Modbus TCP on host:port (0 = any free port)."""
    gate = _Gate(drives, answer_unknown=True)
    server = ModbusTcpServer(
        _sim_devices(drives, catch_all=True),
        framer=FramerType.SOCKET,
        address=(host, port),
        trace_pdu=gate.trace_pdu,
    )
    await server.serve_forever(background=True)
    bound = server.transport.sockets[0].getsockname()[1]
    return ModbusEndpoint(
        url=f"tcp://{host}:{bound}", port=bound, path=None, server=server, gate=gate
    )


class _PtyBridge:
    """Two ptys whose masters are cross-connected: slave A <-> slave B."""

    def __init__(self, loop: asyncio.AbstractEventLoop) -> None:
        self._loop = loop
        self._fds: list[int] = []
        try:
            m_a, s_a = os.openpty()
            self._fds += [m_a, s_a]
            m_b, s_b = os.openpty()
            self._fds += [m_b, s_b]
            for fd in (s_a, s_b):
                tty.setraw(fd)  # no echo / line editing before a client opens it
            for fd in (m_a, m_b):
                os.set_blocking(fd, False)
            self.server_path = os.ttyname(s_a)
            self.client_path = os.ttyname(s_b)
        except BaseException:
            self._close_fds()
            raise
        self._masters = (m_a, m_b)
        loop.add_reader(m_a, self._pump, m_a, m_b)
        loop.add_reader(m_b, self._pump, m_b, m_a)

    def _pump(self, src: int, dst: int) -> None:
        try:
            data = os.read(src, 4096)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            return
        with contextlib.suppress(BlockingIOError, InterruptedError, OSError):
            os.write(dst, data)  # a full buffer (nobody reading) drops the bytes

    def close(self) -> None:
        for fd in self._masters:
            self._loop.remove_reader(fd)
        self._close_fds()

    def _close_fds(self) -> None:
        for fd in self._fds:
            with contextlib.suppress(OSError):
                os.close(fd)
        self._fds = []


async def serve_modbus_rtu_pty(drives: Mapping[int, DriveModel], baud: int = 19200) -> ModbusEndpoint:
    """Serve `drives` as Modbus RTU on a pty; the client opens `endpoint.path`."""
    bridge = _PtyBridge(asyncio.get_running_loop())
    try:
        gate = _Gate(drives, answer_unknown=False)
        server = ModbusSerialServer(
            _sim_devices(drives, catch_all=False),
            framer=FramerType.RTU,
            port=bridge.server_path,
            baudrate=baud,
            bytesize=8,
            parity="N",
            stopbits=1,
            trace_pdu=gate.trace_pdu,
        )
        await server.serve_forever(background=True)
    except BaseException:
        bridge.close()
        raise
    return ModbusEndpoint(
        url=f"rtu://{bridge.client_path}?baud={baud}",
        port=None,
        path=bridge.client_path,
        server=server,
        gate=gate,
        bridge=bridge,
    )
