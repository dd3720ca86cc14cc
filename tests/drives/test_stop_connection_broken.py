"""A stop word whose TCP connection breaks under it (reset or closed by the peer) is sent again on
a new connection, within the stop's retry budget, and the stop reports no error when the retry
got through (drives/stop.py `passing`); the break is told at once, not after the request
timeout. A drive where nothing answers at the address (its connect times out) is not retried and
delays the other drive's stop word by one connect timeout at most; a drive the link keeps
unaddressed (drives/starve.py) is not retried either. The simulator's drives behind its real
Modbus TCP server; the break is made by a TCP proxy between the link and the server (the
simulator cannot drop a connection under a request), the dead address by a listener whose
accept queue is full (its connects are never answered)."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import socket
import struct
import time

import pytest
from support.drives_testkit import CW_EMERGENCY, CW_RUN, SimDrives

from drives.connection import CONNECT_EXTRA_S
from drives.drive import Drive
from drives.errors import DriveConnectError, DriveLinkDropped, DriveLinkError
from drives.link import ModbusLink
from drives.pair import drive_names
from drives.stop import send_stop

pytestmark = pytest.mark.timeout(60)

CW = 0  # register address
TIMEOUT_S = 1.0  # the links' request timeout: a retry after a timeout would cost this much


class BreakingProxy:
    """Forwards Modbus TCP between the link and the simulator; the first FC06 write of CW to
    device `dev` (`read`: its first FC03 read) is not forwarded: the link's connection is reset
    (`how` "reset") or closed."""

    def __init__(self, upstream: str, dev: int, how: str, *, read: bool = False):
        self.host, port = upstream.removeprefix("tcp://").split(":")
        self.port, self.dev, self.how, self.read = int(port), dev, how, read
        self.broken: list[int] = []  # the CW values of the writes not forwarded (a read: its address)
        self.connections = 0
        self.server: asyncio.Server | None = None

    async def start(self) -> str:
        self.server = await asyncio.start_server(self._serve, "127.0.0.1", 0)
        return f"tcp://127.0.0.1:{self.server.sockets[0].getsockname()[1]}"

    async def _serve(self, r: asyncio.StreamReader, w: asyncio.StreamWriter) -> None:
        self.connections += 1
        ur, uw = await asyncio.open_connection(self.host, self.port)
        back = asyncio.create_task(self._back(ur, w))
        try:
            while True:
                head = await r.readexactly(7)  # MBAP: tid, protocol, length, unit id
                body = await r.readexactly(struct.unpack(">H", head[4:6])[0] - 1)
                fc, address = body[0], struct.unpack(">H", body[1:3])[0]
                chosen = fc == 3 if self.read else (fc == 6 and address == CW)
                if head[6] == self.dev and chosen and not self.broken:
                    self.broken.append(address if self.read else struct.unpack(">H", body[3:5])[0])
                    self._break(w)
                    return
                uw.write(head + body)
                await uw.drain()
        except (asyncio.IncompleteReadError, ConnectionError):
            pass
        finally:
            back.cancel()
            uw.close()

    def _break(self, w: asyncio.StreamWriter) -> None:
        if self.how == "reset":
            w.get_extra_info("socket").setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
            w.transport.abort()  # RST
        else:
            w.close()  # FIN

    @staticmethod
    async def _back(ur: asyncio.StreamReader, w: asyncio.StreamWriter) -> None:
        with contextlib.suppress(ConnectionError):  # either side's connection gone
            while data := await ur.read(4096):
                w.write(data)
                await w.drain()

    async def aclose(self) -> None:
        assert self.server is not None
        self.server.close()


@pytest.fixture(autouse=True)
def _running(tcp_sim: SimDrives) -> None:
    for dev in (1, 2):
        tcp_sim.models[dev].write(CW, [CW_RUN])
        tcp_sim.models[dev].write(1, [1000])


def _pair(spin: ModbusLink, orbit: ModbusLink) -> list[Drive]:
    return [Drive(spin, 1, "spin", bidirectional=False), Drive(orbit, 2, "orbit", bidirectional=True)]


@pytest.mark.parametrize("how", ["reset", "close"])
@pytest.mark.parametrize("dev", [1, 2])
async def test_stop_word_whose_connection_breaks_is_sent_again_on_a_new_connection(tcp_sim, how, dev):
    proxy = BreakingProxy(tcp_sim.url, dev, how)
    url = await proxy.start()
    try:
        async with ModbusLink(url, timeout=TIMEOUT_S, names=drive_names(1, 2)) as link:
            t0 = time.monotonic()
            errors = await send_stop(_pair(link, link), emergency=True)
            took = time.monotonic() - t0
            connects = link.connects
    finally:
        await proxy.aclose()
    assert proxy.broken == [CW_EMERGENCY], f"the proxy broke no stop word: {proxy.broken}"
    for d in (1, 2):
        regs = tcp_sim.regs(d)
        assert (regs["CW"], regs["REF"]) == (CW_EMERGENCY, 0), (
            f"drive {d} holds CW {regs['CW']:#06x}, REF {regs['REF']} after the stop "
            f"(connection of drive {dev}'s word {how}): stop errors {[str(e) for e in errors]}"
        )
    assert errors == [], [str(e) for e in errors]
    assert connects == 2 and proxy.connections == 2  # the retry went out on a new connection
    assert took < TIMEOUT_S / 2, f"the stop took {took:.2f} s: the broken connection waited out the timeout"


async def test_a_broken_connection_is_told_as_dropped_at_once(tcp_sim):
    proxy = BreakingProxy(tcp_sim.url, 1, "reset")
    url = await proxy.start()
    try:
        async with ModbusLink(url, timeout=TIMEOUT_S) as link:
            t0 = time.monotonic()
            with pytest.raises(DriveLinkDropped, match="connection lost under the request"):
                await link.write(1, CW, [CW_EMERGENCY])
            assert time.monotonic() - t0 < TIMEOUT_S / 2
            assert not link.connected and link.failures == 1
            await link.write(1, CW, [CW_EMERGENCY])  # the next request: a new connection
            assert link.connects == 2
    finally:
        await proxy.aclose()
    assert tcp_sim.regs(1)["CW"] == CW_EMERGENCY


async def test_a_poll_read_whose_connection_breaks_is_a_failure_not_a_read_given_way(tcp_sim):
    """A poll's read (`gives_way`) whose connection breaks is the link's failure, told at once:
    not taken for a read given up to a stop, which the poll counts as no failure (its dead-link
    count would never grow on a connection reset at every read)."""
    proxy = BreakingProxy(tcp_sim.url, 1, "reset", read=True)
    url = await proxy.start()
    try:
        async with ModbusLink(url, timeout=TIMEOUT_S) as link:
            t0 = time.monotonic()
            with pytest.raises(DriveLinkDropped, match="connection lost under the request"):
                await link.read(1, CW, 2, gives_way=True)
            assert time.monotonic() - t0 < TIMEOUT_S / 2
            assert (link.failures, link.connected) == (1, False)
            assert await link.read(1, CW, 2, gives_way=True) == [CW_RUN, 1000]  # a new connection
    finally:
        await proxy.aclose()
    assert proxy.broken == [CW]


async def test_an_idempotent_write_whose_connection_breaks_is_retried_by_the_link(tcp_sim):
    """A speed command's words (`retries`: Drive.write_retries) go again on a new connection
    at once, as they did after the timeout a broken connection used to end in."""
    proxy = BreakingProxy(tcp_sim.url, 2, "reset")
    url = await proxy.start()
    try:
        async with ModbusLink(url, timeout=TIMEOUT_S) as link:
            t0 = time.monotonic()
            await link.write(2, CW, [CW_EMERGENCY], retries=1)
            assert time.monotonic() - t0 < TIMEOUT_S / 2
            assert (link.retries, link.connects, link.failures) == (1, 2, 1)
    finally:
        await proxy.aclose()
    assert proxy.broken == [CW_EMERGENCY] and tcp_sim.regs(2)["CW"] == CW_EMERGENCY


@pytest.fixture
def dead_address():
    """tcp://127.0.0.1:port where a connect is never answered: a listener whose accept queue is full."""
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(0)
    port = listener.getsockname()[1]
    filling = []
    for _ in range(3):
        c = socket.socket()
        c.setblocking(False)
        c.connect_ex(("127.0.0.1", port))
        filling.append(c)
    time.sleep(0.05)
    try:
        yield f"tcp://127.0.0.1:{port}"
    finally:
        for c in [*filling, listener]:
            c.close()


async def test_a_drive_where_nothing_answers_costs_one_connect_timeout_and_is_not_retried(
    tcp_sim, dead_address, monkeypatch
):
    """The spin drive's link goes to a dead address, the orbit drive's to the simulator: the
    orbit drive's stop word arrives one connect timeout (request timeout + CONNECT_EXTRA_S) after
    the stop began, not more; the spin drive's word and its zero reference are tried once each."""
    timeout = 0.3
    connect_s = timeout + CONNECT_EXTRA_S
    orbit, real = tcp_sim.models[2], tcp_sim.models[2].write
    arrived: list[float] = []

    def write(address, values):
        if address == CW:
            arrived.append(time.monotonic())
        real(address, values)

    monkeypatch.setattr(orbit, "write", write)
    dead = ModbusLink(dead_address, timeout=timeout, names=drive_names(1, 2))
    async with ModbusLink(tcp_sim.url, timeout=timeout, names=drive_names(1, 2)) as live:
        t0 = time.monotonic()
        errors = await send_stop(_pair(dead, live), emergency=True)
        took = time.monotonic() - t0
    await dead.close()
    assert (tcp_sim.regs(2)["CW"], tcp_sim.regs(2)["REF"]) == (CW_EMERGENCY, 0)
    assert len(arrived) == 1 and connect_s - 0.05 <= arrived[0] - t0 <= connect_s + 0.4, (
        f"the orbit drive's stop word came {arrived[0] - t0:.2f} s after the stop began (one connect: {connect_s} s)"
    )
    assert [(type(e), e.drive) for e in errors] == [(DriveConnectError, 1)]
    # CW and REF tried once each on the dead link: two connect timeouts, not 2 x (1 + 2 retries)
    assert took <= 2 * connect_s + 0.5, f"the stop took {took:.2f} s: the dead address was retried"


async def test_a_drive_the_link_keeps_unaddressed_is_not_retried(tcp_sim, caplog):
    """drives/starve.py starves a drive's watchdog on purpose: the link refuses its requests
    (DriveLinkError, not a broken connection), and the stop does not try it again."""
    async with ModbusLink(tcp_sim.url, timeout=0.3, names=drive_names(1, 2)) as link:
        link.unaddressed[1] = "its watchdog is starved"
        with caplog.at_level(logging.WARNING, logger="drives.stop"):
            errors = await send_stop(_pair(link, link), emergency=True)
    assert [(type(e), e.drive) for e in errors] == [(DriveLinkError, 1)]
    assert not [r for r in caplog.records if "trying again" in r.getMessage()], caplog.text
    assert tcp_sim.regs(1)["CW"] == CW_RUN and tcp_sim.regs(2)["CW"] == CW_EMERGENCY
