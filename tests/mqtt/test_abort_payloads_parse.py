"""Stop and abort are always accepted, also when their payload is over the size or nesting
limits of a command or repeats a key with the same value; an id too long to echo is not
cut short but left out (null) and said so; messages on the abort topic that are not a stop
or an abort get the reason they cannot be read, and an empty one (a retained message
being cleared) gets no reply at all."""

from __future__ import annotations

import json

import pytest

from orbitrig.service.abort_copies import Connection
from orbitrig.service.inbox import CommandInbox, CommandTriage
from orbitrig.service.protocol import MAX_COMMAND_BYTES, CommandError, parse_command

BIG = "x" * 5000  # over MAX_COMMAND_BYTES


def stop_with(**fields) -> bytes:
    return json.dumps({"cmd": "stop", "id": "s", **fields}).encode()


def nested(depth: int) -> str:
    return "[" * depth + "]" * depth


@pytest.mark.parametrize(
    "payload, why",
    [
        (stop_with(note=BIG), "payload too large"),
        (b'{"cmd":"stop","id":"s","n":' + nested(40).encode() + b"}", "nested too deeply"),
        (b'{"cmd":"stop","id":"s","n":' + nested(1300).encode() + b"}", "nested too deeply"),  # beyond the parser
        (b'{"cmd":"stop","id":"s","n":' + b'{"a":' * 300 + b"1" + b"}" * 300 + b',"cmd":"\\u0073top"}', "nested"),
        (b'{"cmd":"stop","id":"s","n":' + nested(40).encode() + b',"big":"' + BIG.encode() + b'"}', "too large"),
    ],
    ids=["5000-bytes", "nested-40", "nested-1300", "deep-objects-cmd-twice", "both"],
)
def test_a_stop_beyond_the_limits_of_a_command_is_accepted(payload, why):
    cmd = parse_command(payload)
    assert cmd.cmd == "stop" and cmd.id == "s"
    assert any(why in problem for problem in cmd.ignored), cmd.ignored  # logged as overlooked


def deep_stop(chars: int) -> bytes:
    """A stop nested beyond the parser's depth, ``chars`` characters long."""
    head, tail = b'{"cmd":"stop","id":"s","n":', b"}"
    depth = (chars - len(head) - len(tail)) // 2
    return head + nested(depth).encode() + b" " * (chars - len(head) - len(tail) - 2 * depth) + tail


@pytest.mark.parametrize(
    "accepted, refused",
    [
        (stop_with(note=BIG), json.dumps({"cmd": "status", "id": "q", "note": BIG}).encode()),
        (
            b'{"cmd":"stop","id":"s","n":' + nested(40).encode() + b"}",
            b'{"cmd":"status","id":"q","n":' + nested(40).encode() + b"}",
        ),
        (
            b'{"cmd":"stop","id":"s","n":' + nested(1300).encode() + b"}",
            b'{"cmd":"stop","id":"s","n":' + nested(1300).encode()[:-1] + b"}",  # not JSON: no stop
        ),
        (
            b'{"cmd":"stop","id":"s","n":[' + nested(300).encode() + b",1]}",
            b'{"cmd":"stop","id":"s","n":[' + nested(300).encode() + b",1,]}",  # not JSON either
        ),
        (
            b'{"cmd":"stop","cmd":"stop","id":"s","n":' + nested(40).encode() + b"}",
            b'{"cmd":"stop","cmd":"status","id":"s","n":' + nested(40).encode() + b"}",  # which one was meant?
        ),
        (stop_with(note="x" * 65000), stop_with(note="x" * 65536)),  # MAX_STOP_BYTES 65536
        (deep_stop(16384), deep_stop(16385)),  # read token by token: at most MAX_DEEP_STOP_CHARS
    ],
    ids=["size", "nesting", "deep-not-json", "deep-bad-json", "cmd-twice", "stop-size-limit", "deep-size-limit"],
)
def test_only_an_unambiguous_stop_or_abort_is_read_beyond_the_limits(accepted, refused):
    assert parse_command(accepted).cmd == "stop"
    with pytest.raises(CommandError):
        parse_command(refused)


def test_a_key_repeated_with_the_same_value_is_not_ambiguous():
    cmd = parse_command(b'{"cmd":"abort","cmd":"abort","id":"a-1","id":"a-1"}')
    assert (cmd.cmd, cmd.id, cmd.ignored) == ("abort", "a-1", ())
    assert parse_command(b'{"cmd":"status","cmd":"status","id":"q"}').cmd == "status"
    with pytest.raises(CommandError, match="'cmd' given more than once"):
        parse_command(b'{"cmd":"abort","cmd":"stop","id":"a-2"}')  # which one was meant: refused
    with pytest.raises(CommandError, match="'id' given more than once"):
        parse_command(b'{"cmd":"status","id":1,"id":true}')  # 1 and true are not the same value


def test_an_id_too_long_is_not_echoed_cut_short():
    long_id = "i" * 200
    with pytest.raises(CommandError) as refused:
        parse_command(json.dumps({"cmd": "status", "id": long_id}))
    assert refused.value.id is None and "1 to 128 characters" in refused.value.reason
    cmd = parse_command(json.dumps({"cmd": "abort", "id": long_id}))  # carried out all the same
    assert cmd.cmd == "abort" and cmd.id is None
    assert cmd.id_note == "the id sent is not echoed: it has 200 characters (at most 128)"
    assert parse_command(json.dumps({"cmd": "abort", "id": "i" * 128})).id == "i" * 128


def triage_with_replies() -> tuple[CommandTriage, list, list]:
    handled: list[bytes] = []
    replies: list[tuple[str | None, str]] = []
    triage = CommandTriage(lambda payload, retained: handled.append(payload), lambda *r: replies.append(r), lambda: 0)
    return triage, handled, replies


@pytest.mark.parametrize(
    "payload, reason",
    [
        (b"abort", "payload is not JSON: Expecting value at line 1 column 1"),
        (b'{"cmd":"abort","id":"t-1"', "payload is not JSON: Expecting ',' delimiter"),
        (b'{"id":"t-2"}', "missing field 'cmd'"),
        (b'{"cmd":["abort"],"id":"t-3"}', "field 'cmd' must be a string, got array"),
    ],
)
def test_the_abort_topic_says_why_a_message_cannot_be_read(payload, reason):
    triage, handled, replies = triage_with_replies()
    triage.urgent(payload, False, via=Connection.ABORT)
    assert handled == [] and len(replies) == 1
    assert replies[0][1].startswith(reason) and "not None" not in replies[0][1], replies


def test_an_empty_message_is_never_answered():
    """Publishing an empty retained message clears a retained one (the docs tell operators
    to): the broker passes it on to the service, which does not answer it, on either topic."""
    triage, handled, replies = triage_with_replies()
    for via in Connection:
        triage.urgent(b"", False, via=via)
        triage.urgent(b"", True, via=via)
    assert triage.at_once(b"", False) is True  # dealt with on the command topic: never queued
    assert triage.shed(b"", False) is True  # (also while commands wait: no "busy")
    assert handled == [] and replies == []


def test_a_retained_message_on_the_abort_topic_is_answered_once():
    """Handed over on each subscription, to each connection: not a copy to pair. A stop or an
    abort goes to handle (which carries a retained one out once in the service's life);
    anything else is answered off the main connection only."""
    triage, handled, replies = triage_with_replies()
    for via in (Connection.ABORT, Connection.MAIN):
        triage.urgent(b'{"cmd":"status","id":"r-1"}', True, via=via)
        triage.urgent(b'{"cmd":"abort","id":"r-2"}', True, via=via)
    assert handled == [b'{"cmd":"abort","id":"r-2"}'] * 2
    assert [cid for cid, _ in replies] == ["r-1"]


def test_a_busy_reply_carries_no_id_cut_short():
    triage, _, replies = triage_with_replies()
    triage.overflow(json.dumps({"cmd": "status", "id": "i" * 200}).encode(), False)
    assert replies and replies[0][0] is None


def test_at_once_recognises_a_stop_beyond_the_limits():
    triage, handled, _ = triage_with_replies()
    inbox = CommandInbox(take_now=lambda m: triage.at_once(m, False), overflow=lambda m: None)
    payload = stop_with(note=BIG)
    assert len(payload) > MAX_COMMAND_BYTES
    inbox.put_nowait(payload)
    assert handled == [payload] and inbox.empty()
