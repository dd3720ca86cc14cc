"""The main connection left unread after a stop or an abort (orbitrig/service/flood_read.py's
hold_reading), on a real socket watched by a real event loop: an abort's hold asked within a
stop's lasts until its stop words are out, not only as long as the stop's."""

from __future__ import annotations

import asyncio
import contextlib
import socket

from orbitrig.service.flood_read import hold_reading


class _Connection:
    """What hold_reading asks of paho's client: the socket it reads (here one end of a real pair)."""

    def __init__(self, sock: socket.socket) -> None:
        self._sock = sock

    def socket(self) -> socket.socket:
        return self._sock


@contextlib.contextmanager
def _watched_pair():
    """(connection, the peer's socket, the event set when the loop finds the connection readable):
    one end of a real socket pair watched by the running loop, as aiomqtt watches paho's."""
    loop = asyncio.get_running_loop()
    ours, theirs = socket.socketpair()
    ours.setblocking(False)
    read = asyncio.Event()
    loop.add_reader(ours.fileno(), read.set)
    try:
        yield _Connection(ours), theirs, read
    finally:
        loop.remove_reader(ours.fileno())
        ours.close()
        theirs.close()


async def test_an_abort_held_within_a_stop_s_hold_keeps_the_connection_unread_until_its_words_are_out():
    """A stop holds the connection for 0.05 s; an abort 0.01 s later holds it until its stop words
    are out (at most 5 s here). The connection stays unread past the stop's 0.05 s while the words
    go out and is read again once they are (the abort's hold was refused, "held already", and the
    flood read again after the stop's 0.05 s)."""
    loop = asyncio.get_running_loop()
    with _watched_pair() as (connection, theirs, read):
        assert hold_reading(connection, 0.05)
        await asyncio.sleep(0.01)
        words = loop.create_future()  # the abort's stop words going out
        assert hold_reading(connection, 5.0, words)
        theirs.send(b"flood")
        await asyncio.sleep(0.3)  # well past the stop's hold
        assert not read.is_set()
        words.set_result(None)
        await asyncio.wait_for(read.wait(), 2)


async def test_a_hold_ends_at_its_time_or_when_its_words_are_out_whichever_comes_first():
    """Held until the words are out (read again at once then, not after the 5 s), or for 0.05 s
    when the words take longer; either way the connection is read with its own callback again."""
    loop = asyncio.get_running_loop()
    with _watched_pair() as (connection, theirs, read):
        theirs.send(b"flood")
        words = loop.create_future()
        assert hold_reading(connection, 5.0, words)
        await asyncio.sleep(0.1)
        assert not read.is_set()
        words.set_result(None)
        await asyncio.wait_for(read.wait(), 2)
        read.clear()
        never = loop.create_future()
        assert hold_reading(connection, 0.05, never)
        await asyncio.wait_for(read.wait(), 2)
        never.cancel()
