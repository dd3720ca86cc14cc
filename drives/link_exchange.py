"""One request's exchange on the connection under a ModbusLink (drives/link.py): sent, answered,
checked, or given up.

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
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Awaitable, Callable, Mapping, Sequence
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
from drives.link_url import parse_modbus_url
from drives.rtu import RtuGarbled, RtuLine
from drives.turns import Turns

if TYPE_CHECKING:
    from pymodbus.client import AsyncModbusTcpClient

# The answer of a request: pymodbus' response PDU (TCP) or RtuAnswer (RTU), both with
# dev_id, function_code, registers, exception_code and isError(); pymodbus types its
# responses per function code, so the common shape is not a declared type.
Answer = Any
Call = Callable[["RtuLine | AsyncModbusTcpClient"], Awaitable[Answer]]
Span = tuple[int, int]  # (first address, count) of the registers a request covers
#: asked once a request has the link (`ModbusLink.write`): False, the request is not sent
Guard = Callable[[], bool] | None

log = logging.getLogger("drives.link")  # the link's messages keep its logger's name


async def _within(request: Awaitable[Answer], seconds: float) -> Answer:
    """`request`, or TimeoutError after `seconds` (one task: wait_for's inner task of 3.11 ended
    unwatched when the line closed under a cancelled request, and its failure was reported)."""
    async with asyncio.timeout(seconds):
        return await request


def _seen(exchange: asyncio.Future[Any]) -> None:
    """Mark an exchange's failure as seen: one a cancelled caller left behind (RTU: settled
    before the next request; TCP: dropped) ends unwatched, often failing as the line closes."""
    if not exchange.cancelled():
        exchange.exception()


class LinkExchange:
    """The connection under a ModbusLink and each request's exchange on it: opened on demand,
    dropped after a failure, one exchange at a time (`_lock`), its answer checked or given up.
    The base of ModbusLink, which documents the parameters."""

    def __init__(self, url: str, *, timeout: float = 1.0, names: Mapping[int, str] | None = None):
        self.url = url
        self.address = parse_modbus_url(url)
        self.timeout = float(timeout)
        self.names = dict(names or {})
        self._client: RtuLine | AsyncModbusTcpClient | None = None
        self._lock = Turns()  # a stop's requests go before the others waiting (`urgent`)
        self._abandoned: asyncio.Future[Answer] | None = None  # RTU exchange of a cancelled caller
        self._give_way: asyncio.Future[None] | None = None  # set by a stop: the read in flight gives way
        self._lost: asyncio.Future[None] | None = None  # done once the TCP connection is lost
        self.requests = 0  # answered requests (including exception responses)
        self.failures = 0  # requests without a valid answer
        self.failed: ErrorContext = {}  # the drive and registers of the last request without one
        self.connects = 0  # successful (re)connections
        self.retries = 0  # read and write retries after a timeout or a broken connection
        self.unaddressed: dict[int, str] = {}  # device id -> why no request goes to it (DriveLinkError)
        self.late = LateWrites(self.timeout)  # TCP writes given up that may still reach their drive

    # -- connection -------------------------------------------------------------
    @property
    def connected(self) -> bool:
        return self._client is not None and self._client.connected

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

    def _error_kw(self, device_id: int, span: Span) -> ErrorContext:
        """The error context of a request on registers `span` = (first address, count): a
        multi-register request is named as its whole range (an exception answer does not
        say which register of it was refused)."""
        address, count = span
        return {"drive": device_id, "drive_name": self.names.get(device_id), "register": address, "count": count}

    def _failure(self, kw: ErrorContext) -> None:
        """A request on `kw`'s drive and registers got no valid answer: counted, named (`failed`)."""
        self.failures += 1
        self.failed = kw

    def _fail(self, device_id: int, span: Span, what: str) -> NoReturn:
        kw = self._error_kw(device_id, span)
        self._failure(kw)
        self._drop()
        raise DriveLinkDropped(f"{what} on {self.url}", **kw)

    async def _request(
        self,
        device_id: int,
        span: Span,
        function_code: int,
        call: Call,
        urgent: bool = False,
        guard: Guard = None,
        gives_way: bool = False,
        values: Sequence[int] = (),
    ) -> Answer:
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
                self._failure(kw)
                if self.address.kind == "tcp":
                    self._abandon(device_id, span, values, urgent)  # a new connection cannot receive the late answer
                # RTU: the line stays open; it settles (a late answer lands and is
                # discarded) before the next request
                came = f": {err}" if isinstance(err, RtuGarbled) else ""
                raise DriveTimeoutError(f"no answer within {self.timeout:g} s on {self.url}{came}", **kw) from err
            except (ConnectionException, ModbusException, OSError) as err:
                self._failure(kw)
                self._abandon(device_id, span, values, urgent)
                raise DriveLinkDropped(f"link failure on {self.url}: {err}", **kw) from err
            return self._checked(rsp, device_id, span, function_code)

    def _checked(self, rsp: Answer, device_id: int, span: Span, function_code: int) -> Answer:
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

    def _abandon(self, device_id: int, span: Span, values: Sequence[int], urgent: bool) -> None:
        """Drop the connection under a request given up, with a reset on TCP; a TCP write given up
        is recorded as one that may still arrive, a stop's (`urgent`) as one (drives/late.py)."""
        tcp = self.address.kind == "tcp"
        if tcp and values:
            self.late.note(device_id, span[0], values, stop=urgent)
        self._drop(reset=tcp)

    async def _answer(self, exchange: asyncio.Future[Answer], gives_way: bool, kw: ErrorContext) -> Answer:
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

    async def _ensure_connected_for(self, device_id: int, span: Span) -> None:
        try:
            await self._ensure_connected()
        except DriveLinkError as err:
            kw = self._error_kw(device_id, span)
            self._failure(kw)
            raise type(err)(err.reason, **kw) from err  # DriveConnectError stays one
