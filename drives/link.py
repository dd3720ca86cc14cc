"""One async Modbus link (TCP or RTU) shared by the drives on one network.

    link = ModbusLink("tcp://127.0.0.1:5020")          # or "rtu:///dev/pts/3?baud=19200"
    async with link:
        words = await link.read(1, 0, 7)                 # device id, address, count
        await link.write(2, 1, [0xFC18])                 # one value: FC06, more: FC16

The pymodbus client is created inside the running loop (`connect`). Requests are serialised by
one lock and bounded by `timeout`; a Modbus exception response is raised as
`DriveExceptionResponse`, never returned. After a failed request a TCP connection is dropped and
the next request reconnects; an RTU line is reopened after a line error (OSError), while after a
timeout it stays open and settles first. A request whose connection broke under it (TCP reset or
closed, told at once, not after the timeout; an RTU line error; an answer that makes no sense) is
a DriveLinkDropped: the next request goes out on a new connection.

Each request's exchange (its answer, a late one's fate, giving way to a stop) is drives/link_exchange.py's.

No request goes to a device id in `unaddressed` (DriveLinkError, checked once the request has
the link): the poll starves that drive's comm-loss watchdog (drives/starve.py). pymodbus' own
reconnect task and retries are switched off: reconnecting is this class' job, at the pace its
callers (the poll) set; a connect may take the request timeout + CONNECT_EXTRA_S (the connection
under the link, made and opened: drives/connection.py)."""

from __future__ import annotations

import logging
from collections.abc import Sequence
from contextlib import AbstractContextManager

from drives.errors import DriveLinkDropped, DriveTimeoutError
from drives.link_exchange import Guard, LinkExchange, Answer, Call, Span
from drives.link_url import LinkAddress, parse_modbus_url
from drives.registers import register_name, registers_name

log = logging.getLogger(__name__)

__all__ = ["Guard", "LinkAddress", "ModbusLink", "parse_modbus_url"]

_FC_READ, _FC_WRITE_SINGLE, _FC_WRITE_MULTIPLE = 3, 6, 16


class ModbusLink(LinkExchange):
    """Async Modbus client for one URL; an async context manager.

    url : `tcp://host:port` or `rtu:///dev/ttyX?baud=19200` (8N1).
    timeout : s for each request's answer (a connect: + CONNECT_EXTRA_S).
    names : device id -> drive name, for error messages.
    """

    # -- connection -------------------------------------------------------------
    async def connect(self) -> None:
        """Open the connection now (it is also opened on demand). Raises DriveLinkError."""
        async with self._lock:
            await self._ensure_connected()

    async def close(self) -> None:
        """Close the connection; idempotent."""
        async with self._lock:
            self._drop()

    def reserved(self) -> AbstractContextManager[None]:
        """A context: while open only urgent requests (a stop's) get the link (drives/turns.py)."""
        return self._lock.reserved()

    async def __aenter__(self) -> ModbusLink:
        await self.connect()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    # -- requests ---------------------------------------------------------------
    async def read(
        self, device_id: int, address: int, count: int, *, retries: int = 0, gives_way: bool = False, stop: bool = False
    ) -> list[int]:
        """Read `count` holding registers (FC03) from `address`: unsigned 16-bit words.

        `retries` : further tries after a request timeout (a late answer) or a broken connection
        (DriveLinkDropped: on a new one); reading is harmless to repeat. Another link error or an
        exception response is not retried.
        `gives_way` (the poll's reads): on TCP, given up unanswered (DriveGaveWay) once a stop
        needs the link, its connection dropped; not retried. `stop`: a stop's own read (urgent).
        """
        rsp = await self._retried(
            device_id,
            (address, count),
            _FC_READ,
            "read",
            retries,
            lambda c: c.read_holding_registers(address, count=count, device_id=device_id),
            stop,
            gives_way=gives_way,
        )
        words = list(rsp.registers)
        if len(words) != count:
            self._fail(device_id, (address, count), f"asked for {count} registers, got {len(words)}")
        return words

    async def write(
        self,
        device_id: int,
        address: int,
        values: Sequence[int],
        *,
        retries: int = 0,
        urgent: bool = False,
        guard: Guard = None,
    ) -> None:
        """Write unsigned 16-bit words from `address`: FC06 for one, FC16 for several.

        `retries` : further tries after a request timeout (DriveTimeoutError) or a
        broken connection (DriveLinkDropped: on a new one), for idempotent writes only (a
        register set to a value: sending it twice is harmless). Each retry is logged; an
        exception response or another link error is never retried. `urgent` (a stop): goes before every request
        waiting for the link (the one under way finishes first). `guard` (a start's words): asked
        once the request has the link, each try; False: not sent (DriveSuperseded), as after a
        stop asked since the command (a stop's words go before it and it must not undo them).
        """
        values = [int(v) for v in values]
        for i, v in enumerate(values):
            if not 0 <= v <= 0xFFFF:
                raise ValueError(f"{register_name(address + i)}: {v} is not a 16-bit word")
        if len(values) == 1:
            fc, call = _FC_WRITE_SINGLE, lambda c: c.write_register(address, values[0], device_id=device_id)
        else:
            fc, call = _FC_WRITE_MULTIPLE, lambda c: c.write_registers(address, values, device_id=device_id)
        await self._retried(device_id, (address, len(values)), fc, "write", retries, call, urgent, guard, values=values)

    async def _retried(
        self,
        device_id: int,
        span: Span,
        function_code: int,
        what: str,
        retries: int,
        call: Call,
        urgent: bool = False,
        guard: Guard = None,
        *,
        gives_way: bool = False,
        values: Sequence[int] = (),
    ) -> Answer:
        """`_request`, tried again up to `retries` times after a timeout or a broken connection
        (each retry logged);
        `span`: (first address, count) of the registers the request covers."""
        attempt = 0
        while True:
            try:
                return await self._request(device_id, span, function_code, call, urgent, guard, gives_way, values)
            except (DriveTimeoutError, DriveLinkDropped) as err:
                if attempt >= retries:
                    raise
                attempt += 1
                self.retries += 1
                log.warning(
                    "%s (id %d) %s %s: %s; retry %d of %d",
                    self.names.get(device_id, "drive"),
                    device_id,
                    register_name(span[0]) if span[1] == 1 else registers_name(*span),
                    what,
                    err.reason,
                    attempt,
                    retries,
                )
