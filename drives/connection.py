"""The connection under a ModbusLink: pymodbus' TCP client or our RTU master (`RtuLine`),
made for the link's address and opened within a time bound.

pymodbus' own reconnect task and retries are switched off (reconnect_delay=0, retries=0):
reconnecting is the link's job, at the pace its callers (the poll) set. A TCP connect may take
the request timeout + CONNECT_EXTRA_S (pymodbus' `timeout_connect`, also its answers' timeout,
is set to that for the connect only); an RTU line opens at once. A TCP connection lost under a
request is told at once (`watch_loss`): pymodbus itself lets the request wait out its timeout.
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
import struct
from typing import TYPE_CHECKING

from drives.errors import DriveConnectError
from drives.link_url import LinkAddress
from drives.rtu import RtuLine
from rigunits import without_noise

if TYPE_CHECKING:
    from pymodbus.client import AsyncModbusTcpClient

#: s a TCP connect may take beyond the request timeout (a busy host, a gateway slow to accept)
CONNECT_EXTRA_S = 0.5
#: s early a timer of the loop may fire (its clock's resolution, with margin)
_TICK_S = 0.01


def new_connection(address: LinkAddress, url: str, timeout: float) -> RtuLine | AsyncModbusTcpClient:
    """A connection (not opened) to `address` (parsed from `url`), `timeout` s per answer."""
    from pymodbus.client import AsyncModbusTcpClient

    if address.kind == "rtu":
        return RtuLine(address.path, baud=address.baud, timeout=timeout)
    # reconnect_delay=0: no pymodbus reconnect task; retries=0: one try per request.
    return AsyncModbusTcpClient(
        address.host, port=address.port, timeout=timeout, retries=0, reconnect_delay=0, name=url
    )


async def open_connection(client: RtuLine | AsyncModbusTcpClient, url: str, seconds: float) -> None:
    """Open `client` within `seconds`, or close it and raise DriveConnectError (another
    exception, a cancellation included, closes it too and goes on)."""
    try:
        # asyncio.timeout, not wait_for: in Python 3.11 wait_for drops a cancel that arrives in
        # the loop step in which the connect ends (the caller is the poll, a run, a command)
        async with asyncio.timeout(seconds):
            ok = await _connect(client, seconds)
    except (TimeoutError, OSError, ConnectNotMade) as err:
        client.close()
        raise DriveConnectError(f"cannot connect to {url}: {_why(err, seconds)}") from err
    except BaseException:
        client.close()
        raise
    if not ok or not client.connected:
        client.close()
        raise DriveConnectError(f"cannot connect to {url}: {_why(ConnectNotMade(), seconds)}")


class ConnectNotMade(Exception):
    """A connect that failed before its time ran out with no error given (pymodbus said no)."""


def _why(err: BaseException, seconds: float) -> str:
    """A failed connect's cause in words (`seconds`: the time it was given)."""
    if isinstance(err, ConnectionRefusedError):
        return "connection refused (nothing listens on that port: a wrong port, or the drives' server off)"
    if isinstance(err, TimeoutError):
        return (
            f"no answer to the connection within {without_noise(seconds):g} s "
            "(a wrong or unreachable host, or a firewall dropping the port)"
        )
    if isinstance(err, ConnectNotMade):
        return f"the connection was not made, and no error given (not a timeout: before its {without_noise(seconds):g} s ran out)"
    if isinstance(err, socket.gaierror):
        return f"host name not found ({err.strerror})"
    if isinstance(err, OSError):  # a serial port's: its own words ("cannot open /dev/ttyUSB0: ...")
        return err.strerror or str(err) or repr(err)
    return repr(err)


def watch_loss(client: RtuLine | AsyncModbusTcpClient) -> asyncio.Future[None] | None:
    """A future done once the opened TCP connection of `client` is lost (reset or closed by the
    peer); None for an RTU line (its failures are raised by the exchange itself). A peer gone
    silent (frozen, unplugged: no FIN nor reset) is never told here: its requests time out, and
    the poll's failed polls in a row declare the link lost (drives/poll.py)."""
    protocol = getattr(client, "ctx", None)
    if protocol is None:
        return None
    lost: asyncio.Future[None] = asyncio.get_running_loop().create_future()
    told = protocol.callback_disconnected

    def disconnected(exc: Exception | None) -> None:
        if not lost.done():
            lost.set_result(None)
        told(exc)

    protocol.callback_disconnected = disconnected
    return lost


def reset_on_close(client: RtuLine | AsyncModbusTcpClient) -> None:
    """Make the next close of `client`'s TCP connection a reset (SO_LINGER 0: RST, not FIN): the
    host's TCP stops retransmitting a request given up at once (a FIN closes after it has been
    delivered, retransmitted as long as it takes), and a well-behaved server drops what it has not
    read. Bytes already on their way still arrive: drives/late.py. Nothing for an RTU line."""
    transport = getattr(getattr(client, "ctx", None), "transport", None)
    sock = transport.get_extra_info("socket") if transport is not None else None
    if sock is not None:
        with contextlib.suppress(OSError):  # a socket closed under us already: nothing to reset; the drop goes on
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))


async def _connect(client: RtuLine | AsyncModbusTcpClient, seconds: float) -> bool:
    """`client.connect()` within `seconds`: pymodbus' `timeout_connect` (its answers' too), raised for it;
    a failed TCP connect raises its OSError (ConnectionRefusedError ...), TimeoutError once `seconds`
    passed, else ConnectNotMade (pymodbus said no, before the time, without an error)."""
    protocol = getattr(client, "ctx", None)
    params = getattr(protocol, "comm_params", None)
    if protocol is None or params is None:  # RtuLine: opening the port does not wait
        return await client.connect()
    create, failed = protocol.call_create, []

    async def create_kept() -> object:  # pymodbus logs a failed connect's error and returns False: keep it
        try:
            return await create()
        except OSError as err:
            failed.append(err)
            raise

    answers, params.timeout_connect = params.timeout_connect, seconds
    protocol.call_create = create_kept
    loop = asyncio.get_running_loop()
    began = loop.time()
    try:
        if await client.connect():
            return True
    finally:
        params.timeout_connect, protocol.call_create = answers, create
    if failed:
        raise failed[0]
    if loop.time() - began >= seconds - _TICK_S:
        raise TimeoutError()  # no error kept: pymodbus' own timeout_connect passed
    raise ConnectNotMade()
