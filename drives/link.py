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

A TCP write given up (no answer in time, its caller cancelled, its connection broken) may still
reach its drive after requests sent since on a new one: its connection is dropped with a reset
(RST) and it is recorded in `late` while it may, a stop's (urgent) marked as one (drives/late.py).

A late answer must never be taken for the answer to a newer request: on TCP a new connection
cannot receive it (and transaction ids differ). RTU has no transaction id: `rtu://` runs on
`drives.rtu.RtuLine` (not pymodbus' serial client), which keeps the inter-frame silence before
every request (longer after a failed exchange, so a late answer lands first) and accepts only a
CRC-valid answer from the addressed device with the request's function code and shape,
discarding any other frame on the line. An exchange whose caller was cancelled is allowed to
finish (<= timeout) before the next one starts.

A stop does not wait for a poll's read (`read(..., gives_way=True)`) on TCP: the read is given up
(DriveGaveWay), its connection dropped and the stop's words go out on a new one (a read changes
nothing in a drive, so no order between it and the stop matters). A write in flight is always
answered (or timed out) first: on another connection the stop could overtake it. On RTU the line
carries one exchange at a time: the stop waits for the one in flight (<= timeout, then the settle
time after a missed answer).

No request goes to a device id in `unaddressed` (DriveLinkError, checked once the request has
the link): the poll starves that drive's comm-loss watchdog (drives/starve.py). pymodbus' own
reconnect task and retries are switched off: reconnecting is this class' job, at the pace its
callers (the poll) set; a connect may take the request timeout + CONNECT_EXTRA_S (the connection
under the link, made and opened: drives/connection.py).
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Awaitable, Callable, Mapping, Sequence
from contextlib import AbstractContextManager
from typing import TYPE_CHECKING, Any, NoReturn

from drives.connection import CONNECT_EXTRA_S, new_connection, open_connection, reset_on_close, watch_loss
from drives.errors import (
    DriveExceptionResponse,
    DriveGaveWay,
    DriveLinkDropped,
    DriveLinkError,
    DriveSuperseded,
    DriveTimeoutError,
    ErrorContext,
)
from drives.late import LateWrites
from drives.link_url import LinkAddress, parse_modbus_url
from drives.registers import register_name, registers_name
from drives.rtu import RtuLine
from drives.turns import Turns

if TYPE_CHECKING:
    from pymodbus.client import AsyncModbusTcpClient

# The answer of a request: pymodbus' response PDU (TCP) or RtuAnswer (RTU), both with
# dev_id, function_code, registers, exception_code and isError(); pymodbus types its
# responses per function code, so the common shape is not a declared type.
_Answer = Any
_Call = Callable[["RtuLine | AsyncModbusTcpClient"], Awaitable[_Answer]]
_Span = tuple[int, int]  # (first address, count) of the registers a request covers
#: asked once a request has the link (`ModbusLink.write`): False, the request is not sent
Guard = Callable[[], bool] | None

log = logging.getLogger(__name__)

__all__ = ["Guard", "LinkAddress", "ModbusLink", "parse_modbus_url"]

_FC_READ, _FC_WRITE_SINGLE, _FC_WRITE_MULTIPLE = 3, 6, 16


async def _within(request: Awaitable[_Answer], seconds: float) -> _Answer:
    """`request`, or TimeoutError after `seconds` (one task: wait_for's inner task of 3.11 ended
    unwatched when the line closed under a cancelled request, and its failure was reported)."""
    async with asyncio.timeout(seconds):
        return await request


def _seen(exchange: asyncio.Future[Any]) -> None:
    """Mark an exchange's failure as seen: one a cancelled caller left behind (RTU: settled
    before the next request; TCP: dropped) ends unwatched, often failing as the line closes."""
    if not exchange.cancelled():
        exchange.exception()


class ModbusLink:
    """Async Modbus client for one URL; an async context manager.

    url : `tcp://host:port` or `rtu:///dev/ttyX?baud=19200` (8N1).
    timeout : s for each request's answer (a connect: + CONNECT_EXTRA_S).
    names : device id -> drive name, for error messages.
    """

    def __init__(self, url: str, *, timeout: float = 1.0, names: Mapping[int, str] | None = None):
        self.url = url
        self.address = parse_modbus_url(url)
        self.timeout = float(timeout)
        self.names = dict(names or {})
        self._client: RtuLine | AsyncModbusTcpClient | None = None
        self._lock = Turns()  # a stop's requests go before the others waiting (`urgent`)
        self._abandoned: asyncio.Future[_Answer] | None = None  # RTU exchange of a cancelled caller
        self._give_way: asyncio.Future[None] | None = None  # set by a stop: the read in flight gives way
        self._lost: asyncio.Future[None] | None = None  # done once the TCP connection is lost
        self.requests = 0  # answered requests (including exception responses)
        self.failures = 0  # requests without a valid answer
        self.connects = 0  # successful (re)connections
        self.retries = 0  # read and write retries after a timeout or a broken connection
        self.unaddressed: dict[int, str] = {}  # device id -> why no request goes to it (DriveLinkError)
        self.late = LateWrites(self.timeout)  # TCP writes given up that may still reach their drive

    # -- connection -------------------------------------------------------------
    @property
    def connected(self) -> bool:
        return self._client is not None and self._client.connected

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

    def _new_client(self) -> RtuLine | AsyncModbusTcpClient:
        return new_connection(self.address, self.url, self.timeout)

    async def _ensure_connected(self) -> None:
        if self.connected:
            return
        self._drop()
        client = self._new_client()
        await open_connection(client, self.url, self.timeout + CONNECT_EXTRA_S)  # DriveConnectError
        self._client, self._lost = client, watch_loss(client)
        self.connects += 1
        log.debug("connected to %s", self.url)

    def _drop(self, *, reset: bool = False) -> None:
        """Close the connection (`reset`: with an RST, its unsent and unread bytes dropped)."""
        if self._abandoned is not None:
            self._abandoned.cancel()
            self._abandoned = None
        if self._client is not None:
            if reset:
                reset_on_close(self._client)
            self._client.close()
            self._client = self._lost = None

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
        span: _Span,
        function_code: int,
        what: str,
        retries: int,
        call: _Call,
        urgent: bool = False,
        guard: Guard = None,
        *,
        gives_way: bool = False,
        values: Sequence[int] = (),
    ) -> _Answer:
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

    def _error_kw(self, device_id: int, span: _Span) -> ErrorContext:
        """The error context of a request on registers `span` = (first address, count): a
        multi-register request is named as its whole range (an exception answer does not
        say which register of it was refused)."""
        address, count = span
        return {"drive": device_id, "drive_name": self.names.get(device_id), "register": address, "count": count}

    def _fail(self, device_id: int, span: _Span, what: str) -> NoReturn:
        self.failures += 1
        self._drop()
        raise DriveLinkDropped(f"{what} on {self.url}", **self._error_kw(device_id, span))

    async def _request(
        self,
        device_id: int,
        span: _Span,
        function_code: int,
        call: _Call,
        urgent: bool = False,
        guard: Guard = None,
        gives_way: bool = False,
        values: Sequence[int] = (),
    ) -> _Answer:
        """One request (`values`: a write's words, recorded if it is given up on TCP, `urgent`: a stop's)."""
        from pymodbus.exceptions import ConnectionException, ModbusException, ModbusIOException

        kw = self._error_kw(device_id, span)
        if urgent and self._give_way is not None and not self._give_way.done():
            self._give_way.set_result(None)  # the poll's read in flight gives the link to the stop
        async with self._lock.turn(urgent):
            if guard is not None and not guard():
                raise DriveSuperseded("not sent: a stop was asked after the command", **kw)
            if device_id in self.unaddressed:  # checked with the link held: nothing queued gets past
                raise DriveLinkError(f"not sent: {self.unaddressed[device_id]}", **kw)
            await self._settle_abandoned()
            await self._ensure_connected_for(device_id, span)
            client = self._client
            if client is None:
                self._fail(device_id, span, "not connected")
            exchange = asyncio.ensure_future(_within(call(client), self.timeout + 0.5))
            exchange.add_done_callback(_seen)  # its failure is raised to the caller, or nobody waits
            try:
                rsp = await self._answer(exchange, gives_way and self.address.kind == "tcp", kw)
            except asyncio.CancelledError:
                if self.address.kind == "tcp" or exchange.done():
                    exchange.cancel()
                    self._abandon(device_id, span, values, urgent)  # a new connection cannot receive the old answer
                else:
                    # RTU: let the exchange finish (<= timeout) before the next request
                    # goes on the line, so its late answer cannot be mistaken for another.
                    self._abandoned = exchange
                raise
            except (ModbusIOException, asyncio.TimeoutError) as err:
                self.failures += 1
                if self.address.kind == "tcp":
                    self._abandon(device_id, span, values, urgent)  # a new connection cannot receive the late answer
                # RTU: the line stays open; it settles (a late answer lands and is
                # discarded) before the next request
                raise DriveTimeoutError(f"no answer within {self.timeout:g} s on {self.url}", **kw) from err
            except (ConnectionException, ModbusException, OSError) as err:
                self.failures += 1
                self._abandon(device_id, span, values, urgent)
                raise DriveLinkDropped(f"link failure on {self.url}: {err}", **kw) from err
            return self._checked(rsp, device_id, span, function_code)

    def _checked(self, rsp: _Answer, device_id: int, span: _Span, function_code: int) -> _Answer:
        """`rsp`, the answer to a request FC`function_code` to `device_id` on `span`, counted; an
        exception answer raised (DriveExceptionResponse), one that does not match: DriveLinkDropped."""
        if rsp is None:
            self._fail(device_id, span, "no response object")
        if rsp.isError():
            self.requests += 1
            said, kw = f"request FC{function_code:02d} refused on {self.url}", self._error_kw(device_id, span)
            raise DriveExceptionResponse(said, exception_code=int(rsp.exception_code), **kw)
        if rsp.function_code != function_code or (rsp.dev_id and rsp.dev_id != device_id):
            what = f"answer FC{rsp.function_code} from id {rsp.dev_id} does not match request FC{function_code}"
            self._fail(device_id, span, what)
        self.requests += 1
        return rsp

    def _abandon(self, device_id: int, span: _Span, values: Sequence[int], urgent: bool) -> None:
        """Drop the connection under a request given up, with a reset on TCP; a TCP write given up
        is recorded as one that may still arrive, a stop's (`urgent`) as one (drives/late.py)."""
        tcp = self.address.kind == "tcp"
        if tcp and values:
            self.late.note(device_id, span[0], values, stop=urgent)
        self._drop(reset=tcp)

    async def _answer(self, exchange: asyncio.Future[_Answer], gives_way: bool, kw: ErrorContext) -> _Answer:
        """The answer of `exchange` (its error raised); a TCP connection lost before it: raised at
        once (ConnectionResetError), not after the timeout. `gives_way` (a poll's read, TCP): given
        up once an urgent request asks for the link before the answer (DriveGaveWay), the connection
        dropped so that the late answer cannot come on the next (pymodbus serves one request at a
        time per connection, and would hold the stop behind it)."""
        ends: list[asyncio.Future[Any]] = [exchange] if self._lost is None else [exchange, self._lost]
        if gives_way:
            self._give_way = give_way = asyncio.get_running_loop().create_future()
            if self._lock.waiting(True):  # a stop came while this read was connecting: at once
                give_way.set_result(None)
            ends.append(give_way)
        gave_way = False
        try:
            await asyncio.wait(ends, return_when=asyncio.FIRST_COMPLETED)
        finally:
            if gives_way:
                self._give_way = None
                gave_way = give_way.done()  # before the cancel below makes it done
                give_way.cancel()
        if exchange.done():
            return exchange.result()
        exchange.cancel()
        if not gave_way:  # the connection was lost under the request
            raise ConnectionResetError("connection lost under the request")  # dropped: DriveLinkDropped
        self._drop()
        raise DriveGaveWay("read given up unanswered: a stop needed the link", **kw)

    async def _settle_abandoned(self) -> None:
        """Wait for the exchange a cancelled caller left on an RTU line (bounded)."""
        exchange = self._abandoned
        if exchange is None:
            return
        await asyncio.wait([exchange])
        self._abandoned = None
        if exchange.cancelled() or isinstance(exchange.exception(), OSError):
            self._drop()

    async def _ensure_connected_for(self, device_id: int, span: _Span) -> None:
        try:
            await self._ensure_connected()
        except DriveLinkError as err:
            self.failures += 1
            raise type(err)(err.reason, **self._error_kw(device_id, span)) from err  # DriveConnectError stays one
