"""The pairing of the two copies of each message on <prefix>/abort (orbitrig.service.inbox
AbortCopies), as explicit sequences of what each connection reads: every abort carried out
once, none swallowed by the copy of an earlier one, none carried out again however late
its second copy comes.

Each connection is what the service has of it: the MQTT client's CommandInbox, a new one
for every (re)connection, made before it connects (AbortCopies learns a reconnection from
a message read off a new one; the abort connection's end from its reader being cancelled).
"""

from __future__ import annotations

import asyncio
import contextlib
import time

import pytest

from orbitrig.service import inbox
from orbitrig.service.abort_copies import AbortCopies, Connection
from orbitrig.service.inbox import CommandInbox, CommandTriage

A1 = b'{"cmd":"abort","id":"estop"}'  # a button bridge's fixed id: every press the same bytes
S1 = b'{"cmd":"stop","id":"s-1"}'


class Side:
    """One of the service's two connections reading <prefix>/abort."""

    def __init__(self, copies: AbortCopies, via: Connection):
        self.copies, self.via = copies, via
        self.connect()

    def connect(self) -> None:
        """A (re)connection: the MQTT client makes a new inbox before it connects."""
        self.inbox = CommandInbox(take_now=lambda message: True, overflow=lambda message: None)

    def lose(self) -> None:
        """The connection ended: aiomqtt cancels the reader waiting on its inbox."""
        if self.inbox.on_end is not None:
            self.inbox.on_end()

    def read(self, payload: bytes) -> bool:
        """True: carried out (first copy); False: dropped (second copy)."""
        return self.copies.first(self.via, payload, self.inbox)


@pytest.fixture
def sides() -> tuple[Side, Side]:
    copies = AbortCopies()
    return Side(copies, Connection.MAIN), Side(copies, Connection.ABORT)


def test_a_copy_of_each_message_is_carried_out_whichever_connection_reads_it_first(sides):
    main, abort = sides
    assert abort.read(A1) and not main.read(A1)  # the abort connection first (a flood on the main one)
    assert main.read(A1) and not abort.read(A1)  # the main one first (the event loop read it first)
    assert abort.read(S1) and not main.read(S1)


@pytest.mark.parametrize("loss_seen", [True, False], ids=["loss-seen", "loss-not-seen"])
def test_an_abort_the_abort_connection_missed_does_not_swallow_the_same_abort_sent_again(sides, loss_seen):
    """The auditor's case: abort #1 reaches only the main connection (the abort connection
    is reconnecting); the operator sends the same bytes again: #2 is carried out off the
    abort connection at once, and its main copy (behind a flood) is then dropped."""
    main, abort = sides
    assert abort.read(A1) and not main.read(A1)  # both connections up
    if loss_seen:
        abort.lose()
    assert main.read(A1)  # #1: the main connection alone has it
    abort.connect()  # reconnected (and subscribed) after #1 was published
    assert abort.read(A1)  # #2: carried out as it arrives, not taken for #1's second copy
    assert not main.read(A1)  # #2's main copy, later: dropped (carried out once)
    assert abort.read(A1) and not main.read(A1)  # and so on, one to one


def test_the_same_abort_sent_again_and_again_is_carried_out_each_time(sides):
    main, abort = sides
    carried = [abort.read(A1) for _ in range(5)]  # five presses; the main connection behind a flood
    carried += [main.read(A1) for _ in range(5)]  # their main copies, in the same order
    assert carried == [True] * 5 + [False] * 5
    carried = [main.read(A1), abort.read(A1), abort.read(A1), main.read(A1)]  # reads interleaved
    assert carried == [True, False, True, False]


def test_a_lagging_main_connection_is_paired_however_far_and_late_behind(sides, monkeypatch):
    """No time window and no small bound: 20000 stops read off the abort connection first,
    their main copies a minute later, each carried out once."""
    main, abort = sides
    stops = [b'{"cmd":"stop","id":"s%d"}' % i for i in range(20_000)]
    first = sum(abort.read(s) for s in stops)
    later = time.monotonic() + 60.0
    monkeypatch.setattr(inbox.time, "monotonic", lambda: later)
    again = sum(main.read(s) for s in stops)
    assert (first, again) == (20_000, 0)


def test_without_connection_identity_too(monkeypatch):
    """The same, called as a bare AbortCopies(): late copies and many copies are second copies."""
    copies = AbortCopies()
    stops = [b'{"cmd":"stop","id":"s%d"}' % i for i in range(300)]
    assert all(copies.first(Connection.ABORT, s) for s in stops)
    later = time.monotonic() + 60.0
    monkeypatch.setattr(inbox.time, "monotonic", lambda: later)
    assert not any(copies.first(Connection.MAIN, s) for s in stops)  # none carried out again


async def test_a_copy_the_main_connection_lost_does_not_swallow_a_later_abort(sides):
    """The main connection's broker queue dropped one copy (a flood); later the abort
    connection is down and an abort with the same bytes reaches the main connection
    only: it is carried out."""
    main, abort = sides
    assert abort.read(A1) and abort.read(A1)  # two presses
    assert not main.read(A1)  # only one main copy: the broker dropped the other
    reader = asyncio.get_running_loop().create_task(abort.inbox.get())  # (aiomqtt's reader)
    await asyncio.sleep(0)
    reader.cancel()  # the abort connection ends: aiomqtt cancels its reader
    with contextlib.suppress(asyncio.CancelledError):
        await reader
    assert abort.copies.up[Connection.ABORT] is False
    assert main.read(A1)  # a third press, the main connection only: carried out
    abort.connect()
    assert abort.read(A1) and not main.read(A1)  # back: one to one again


def test_copies_from_before_a_main_reconnection_are_given_up(sides):
    """The abort connection read a message while the main one was away (QoS 0: the broker
    keeps nothing for it): the main connection never delivers that one; the next one with
    the same bytes is paired with its own copy."""
    main, abort = sides
    assert abort.read(A1)  # main away
    main.connect()
    assert abort.read(A1)  # after the main connection is back
    assert not main.read(A1)  # its copy of the second one
    assert abort.read(A1) and not main.read(A1)


def test_when_the_order_cannot_tell_a_copy_is_carried_out_not_dropped(sides):
    """The abort connection reconnected while the main one lagged: the main connection reads
    an abort published before the abort connection subscribed (which it never gets), then
    the copy of one the abort connection read: neither is dropped, and an abort the abort
    connection reads next is carried out."""
    main, abort = sides
    e = b'{"cmd":"abort","id":"before"}'
    abort.lose()
    abort.connect()
    assert abort.read(S1)  # the abort connection's first message after it subscribed
    assert main.read(e)  # published before that: on the main connection only
    assert main.read(S1)  # (carried out again: which connection missed what cannot be told)
    assert abort.read(e)  # a new abort with those bytes: carried out at once
    assert abort.read(A1) and not main.read(A1)


def test_the_triage_pairs_the_copies_by_the_connection_they_came_off():
    """Through CommandTriage.urgent, from each connection's inbox as the links call it: the
    abort connection reconnected after an abort only the main connection read; the same
    abort sent again is carried out as its abort-connection copy arrives."""
    handled: list[bytes] = []
    replies: list[tuple] = []
    triage = CommandTriage(lambda payload, retained: handled.append(payload), lambda *r: replies.append(r), lambda: 0)

    def connection(via: Connection) -> CommandInbox:
        return CommandInbox(take_now=lambda m: triage.urgent(m, False, via=via) or True, overflow=lambda m: None)

    main, abort = connection(Connection.MAIN), connection(Connection.ABORT)
    abort.put_nowait(A1)
    main.put_nowait(A1)  # #1: one abort
    main.put_nowait(A1)  # #2: the abort connection is reconnecting
    abort = connection(Connection.ABORT)  # (the client of its new connection)
    abort.put_nowait(A1)  # #3: carried out now, not behind the main connection's flood
    assert len(handled) == 3
    main.put_nowait(A1)
    assert handled == [A1] * 3 and replies == [] and triage.counts["second copy"] == 2
