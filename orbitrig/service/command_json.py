"""Reading a command payload into one JSON object, refusing what cannot be read
unambiguously (no I/O).

A payload is refused (:class:`CommandError`) when it is not UTF-8, empty, not
JSON or not an object, and when it is over ``MAX_COMMAND_BYTES`` or nested
deeper than ``MAX_NESTING`` -- unless it is an unambiguous ``stop`` or
``abort`` (its ``cmd`` says so, once, or repeated with the same value): that is
read whole anyway, up to ``MAX_STOP_BYTES`` and at any depth (stop and abort are
always accepted, docs/protocols/mqtt.md), and the limits it exceeds are reported
beside the object (``CommandObject.beyond``). What is read but cannot be trusted
is reported too, for the command parser to judge: keys given twice with
different values (JSON leaves the winner to the parser: the last one here, the
first one elsewhere; the same value twice is not ambiguous) and text fields that
cannot be written back as UTF-8 (a lone surrogate escape such as ``"\\ud800"``),
which no reply could echo.
"""

from __future__ import annotations

import dataclasses
import enum
import itertools
import json
import re
from dataclasses import dataclass
from collections.abc import Callable
from typing import Any

from orbitrig.run.states import RunCommand

#: Largest command payload accepted (bytes); a command is a few dozen bytes.
MAX_COMMAND_BYTES = 4096
#: Deepest nesting of arrays and objects accepted; a command is one level deep.
#: Checked before parsing: the parser's own limit (RecursionError) moves with
#: ``sys.getrecursionlimit()``, which libraries in the same process may raise.
MAX_NESTING = 32
#: Largest stop or abort read beyond those limits (bytes; the parser reads that in about 1 ms)
MAX_STOP_BYTES = 65536
#: Nesting given to the (recursive) JSON parser at most; deeper: read token by token (:func:`_read_deep`)
PARSER_NESTING = 200
#: Longest stop or abort read token by token (characters; some 20 ms of reading on a busy host)
MAX_DEEP_STOP_CHARS = 16384
#: Longest correlation id echoed in a reply (a longer one is not echoed: the reply's id is null)
MAX_ID_CHARS = 128
#: Commands read even beyond the limits (docs/protocols/mqtt.md: always accepted)
STOP_OR_ABORT = frozenset({RunCommand.STOP, RunCommand.ABORT})


def stop_word(name: object) -> RunCommand | None:
    """``RunCommand.STOP`` or ``ABORT`` when ``name`` (a command's ``cmd``) names one in any letter case and
    with blanks around ("ABORT", " Stop "), else None: such a stop is never refused for its
    spelling. Every other command is taken only as the contract spells it."""
    word = name.strip().lower() if isinstance(name, str) else None
    return RunCommand(word) if word in STOP_OR_ABORT else None


_STRING = re.compile(r'"(?:[^"\\]|\\.)*"')
_NOT_BRACKET = re.compile(r"[^\[\]{}]+")
_DEPTH_STEP = {"[": 1, "{": 1, "]": -1, "}": -1}


class CommandError(ValueError):
    """A command payload that is refused. ``id`` is the correlation id when one
    could be read (a string), else None; ``reason`` is the text for the reply."""

    def __init__(self, reason: str, id: str | None = None):
        super().__init__(reason)
        self.reason = reason
        self.id = id


@dataclass(frozen=True)
class CommandObject:
    """The payload's object; ``duplicates``: keys given more than once with different
    values (at any depth; beyond ``PARSER_NESTING``: at the top); ``unencodable``:
    top-level fields whose text is not valid Unicode; ``beyond``: the size and nesting
    limits a stop or abort exceeds (read all the same)."""

    fields: dict[str, Any]
    duplicates: tuple[str, ...] = ()
    unencodable: tuple[str, ...] = ()
    beyond: tuple[str, ...] = ()

    def problems(self) -> list[str]:
        """The reasons to refuse it, for the reply (empty: nothing to object to)."""
        out = list(self.beyond)
        out += [f"key {k!r} given more than once with different values: ambiguous, refused" for k in self.duplicates]
        out += [
            f"field {k!r} cannot be encoded as UTF-8 (a lone surrogate escape such as \\ud800)"
            for k in self.unencodable
        ]
        return out


def encodable(text: str) -> bool:
    """True if ``text`` can be written as UTF-8 (no lone surrogate)."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def nesting(text: str) -> int:
    """The deepest nesting of ``[``/``{`` in JSON text, brackets inside strings
    not counted (unbalanced text counts as far as it goes)."""
    brackets = _NOT_BRACKET.sub("", _STRING.sub("", text))
    return max(itertools.accumulate(map(_DEPTH_STEP.__getitem__, brackets), initial=0))


def type_name(value: Any) -> str:
    """The JSON name of a parsed value's type, for reasons."""
    return {
        dict: "object",
        list: "array",
        str: "string",
        bool: "boolean",
        int: "number",
        float: "number",
        type(None): "null",
    }.get(type(value), type(value).__name__)


def not_a_string(field: str, value: Any) -> str:
    """The reason for a field that must be a string and is not."""
    return f"field {field!r} must be a string, got {type_name(value)}"


def cmd_problem(fields: dict[str, Any]) -> str | None:
    """The reason a command's object names no command: 'cmd' missing or not a string (None: it names one)."""
    if "cmd" not in fields:
        return "missing field 'cmd'"
    return None if isinstance(fields["cmd"], str) else not_a_string("cmd", fields["cmd"])


def unreadable(err: BaseException) -> str:
    """The reason for a payload the parser failed on in a way of its own (no JSON error): its exception's type."""
    return f"payload cannot be read: {type(err).__name__}"


def same(a: Any, b: Any) -> bool:
    """True if two parsed JSON values are the same value (``1`` is not ``true``, NaN is not NaN)."""
    if type(a) is not type(b):
        return False
    if isinstance(a, list):
        return len(a) == len(b) and all(map(same, a, b))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same(v, b[k]) for k, v in a.items())
    return bool(a == b)


def id_problems(fields: dict[str, Any]) -> list[str]:
    """What is wrong with the correlation id (empty: a string of 1 to MAX_ID_CHARS characters)."""
    if "id" not in fields:
        return ["missing field 'id' (a correlation id string)"]
    cid = fields["id"]
    if not isinstance(cid, str):
        return [f"field 'id' must be a string, got {type_name(cid)}"]
    if not 0 < len(cid) <= MAX_ID_CHARS:
        return [f"field 'id' must have 1 to {MAX_ID_CHARS} characters"]
    return []


def echoable_id(found: CommandObject) -> str | None:
    """The correlation id a reply echoes: None unless it is one unambiguous, encodable
    string of 1 to MAX_ID_CHARS characters (an id cut short would not be the id sent)."""
    cid = found.fields.get("id")
    usable = "id" not in found.unencodable and "id" not in found.duplicates and not id_problems(found.fields)
    return cid if usable else None


def read_object(payload: bytes | bytearray | str) -> CommandObject:
    """The JSON object of a payload, or CommandError whatever went wrong (encoding,
    syntax, not an object; size and nesting, unless it is an unambiguous stop or abort)."""
    size = None
    if isinstance(payload, (bytes, bytearray)):
        size = len(payload)
        if size > MAX_STOP_BYTES:
            raise CommandError(_too_large(size))
        try:
            text = bytes(payload).decode("utf-8")
        except UnicodeDecodeError as err:
            raise CommandError(f"payload is not UTF-8: {err.reason} at byte {err.start}") from None
    else:
        text = payload
    text = text.removeprefix("\ufeff")  # a byte order mark some tools write: ignored, as RFC 8259 allows
    if not text.strip():
        raise CommandError("payload is empty: expected a JSON object with 'cmd' and 'id'")
    depth = nesting(text)
    beyond = [_too_large(size)] if size is not None and size > MAX_COMMAND_BYTES else []
    if depth > MAX_NESTING:
        beyond.append(f"payload is not a command: JSON nested too deeply (more than {MAX_NESTING} levels)")
    if not beyond:
        return _read(text)
    if _recent[0] == text:  # (the same payload read again: its first look, then its handling)
        return _recent[1]()
    outcome = _stop_beyond_limits(text, depth, beyond)
    _recent[:] = [text, outcome]
    return outcome()


#: the last payload read beyond the limits, and how that went (reading it can take some ms)
_recent: list[Any] = ["", None]


def _stop_beyond_limits(text: str, depth: int, beyond: list[str]) -> Callable[[], CommandObject]:
    """``text`` beyond the limits ``beyond``: read whole if it may be a stop or an abort, and
    accepted if it is one; the outcome as a call that returns the object or raises why not."""

    def refused(reason: str) -> Callable[[], CommandObject]:
        def refuse() -> CommandObject:
            raise CommandError(reason)

        return refuse

    lower = text.lower()  # (a large payload: once)
    if not any(name in lower for name in STOP_OR_ABORT) and "\\" not in text:
        return refused(beyond[0])  # (it cannot name stop or abort: not read at all)
    if depth > PARSER_NESTING and len(text) > MAX_DEEP_STOP_CHARS:
        return refused(f"{beyond[-1]}; a stop or an abort nested that deeply at most {MAX_DEEP_STOP_CHARS} characters")
    try:
        found = _read(text) if depth <= PARSER_NESTING else _read_deep(text)
    except CommandError:
        return refused(beyond[0])
    if "cmd" in found.duplicates or stop_word(found.fields.get("cmd")) is None:
        return refused(beyond[0])
    accepted = dataclasses.replace(found, beyond=tuple(beyond))
    return lambda: accepted


def _too_large(size: int) -> str:
    return f"payload too large: {size} bytes (at most {MAX_COMMAND_BYTES}; a stop or an abort at most {MAX_STOP_BYTES})"


def _read(text: str) -> CommandObject:
    """``text`` parsed whole (its nesting checked before: at most PARSER_NESTING)."""
    duplicates: list[str] = []

    def pairs(items: list[tuple[str, Any]]) -> dict[str, Any]:
        obj: dict[str, Any] = {}
        for key, value in items:
            if key in obj and key not in duplicates and not same(obj[key], value):
                duplicates.append(key)
            obj[key] = value
        return obj

    try:
        obj = json.loads(text, object_pairs_hook=pairs)
    except json.JSONDecodeError as err:
        raise CommandError(f"payload is not JSON: {err.msg} at line {err.lineno} column {err.colno}") from None
    except RecursionError:
        raise CommandError("payload is not a command: JSON nested too deeply") from None
    except Exception as err:  # noqa: BLE001 - whatever the parser raises, the payload is refused
        raise CommandError(unreadable(err)) from None
    return _object(obj, duplicates)


def _object(obj: Any, duplicates: list[str]) -> CommandObject:
    if not isinstance(obj, dict):
        raise CommandError(f"payload must be a JSON object, got {type_name(obj)}")
    unencodable = tuple(k for k, v in obj.items() if isinstance(v, str) and not encodable(v))
    return CommandObject(obj, tuple(duplicates), unencodable)


class _Next(enum.Enum):
    """What the JSON grammar allows next (:func:`_read_deep`)."""

    VALUE = "value"
    VALUE_OR_CLOSE = "value or ]"
    KEY = "key"
    KEY_OR_CLOSE = "key or }"
    COLON = ":"
    COMMA_OR_CLOSE = ", or a closing bracket"
    END = "end"


_TOKEN = re.compile(
    r'[ \t\n\r]*(?:("(?:[^"\\\x00-\x1f]|\\["\\/bfnrt]|\\u[0-9a-fA-F]{4})*")'
    r"|(-?(?:0|[1-9][0-9]*)(?:\.[0-9]+)?(?:[eE][-+]?[0-9]+)?|true|false|null|NaN|-?Infinity)"
    r"|([\[\]{},:]))"
)
_OPENS = {"]": "[", "}": "{"}


def _read_deep(text: str) -> CommandObject:
    """A JSON object nested too deeply for the parser, checked token by token (no
    recursion); its top-level fields, a nested array or object standing as an empty one."""
    stack: list[str] = []
    fields: list[tuple[str, Any, str]] = []  # (key, value, its text) of the top-level object
    want, key, value_at, pos = _Next.VALUE, "", 0, 0
    while (m := _TOKEN.match(text, pos)) is not None and want is not _Next.END:
        string, scalar, mark = m.groups()
        at, pos = m.start(m.lastindex or 0), m.end()
        if mark in ("[", "{") and want in (_Next.VALUE, _Next.VALUE_OR_CLOSE) and (stack or mark == "{"):
            value_at = at if len(stack) == 1 else value_at
            stack.append(mark)
            want = _Next.KEY_OR_CLOSE if mark == "{" else _Next.VALUE_OR_CLOSE
        elif mark in _OPENS and stack and stack[-1] == _OPENS[mark] and want in _closing(mark):
            stack.pop()
            if len(stack) == 1:
                fields.append((key, [] if mark == "]" else {}, text[value_at:pos]))
            want = _Next.COMMA_OR_CLOSE if stack else _Next.END
        elif mark == ":" and want is _Next.COLON:
            want = _Next.VALUE
        elif mark == "," and want is _Next.COMMA_OR_CLOSE:
            want = _Next.KEY if stack[-1] == "{" else _Next.VALUE
        elif string is not None and want in (_Next.KEY, _Next.KEY_OR_CLOSE):
            key = json.loads(string) if len(stack) == 1 else key
            want = _Next.COLON
        elif mark is None and stack and want in (_Next.VALUE, _Next.VALUE_OR_CLOSE):
            if len(stack) == 1:
                fields.append((key, json.loads(string or scalar), text[at:pos]))
            want = _Next.COMMA_OR_CLOSE
        else:
            raise CommandError(f"payload is not JSON: {want.value} expected at character {at}")
    if want is not _Next.END or text[pos:].strip(" \t\n\r"):
        raise CommandError(f"payload is not JSON: {want.value} expected at character {pos}")
    obj: dict[str, Any] = {}
    raw: dict[str, str] = {}
    duplicates: list[str] = []
    for name, value, value_text in fields:
        if name in obj and name not in duplicates:
            if not (raw[name] == value_text if isinstance(value, (list, dict)) else same(obj[name], value)):
                duplicates.append(name)
        obj[name], raw[name] = value, value_text
    return _object(obj, duplicates)


def _closing(mark: str) -> tuple[_Next, ...]:
    empty = _Next.VALUE_OR_CLOSE if mark == "]" else _Next.KEY_OR_CLOSE
    return (_Next.COMMA_OR_CLOSE, empty)


@dataclass(frozen=True)
class Glance:
    """A first look at a payload: ``name`` the command it names, ``id`` the correlation id
    a reply echoes, each None when it cannot be read; ``problem``: why no name was read."""

    name: str | None
    id: str | None = None
    problem: str | None = None


def glance(payload: bytes) -> Glance:
    """The command a payload names, without validating the rest (the first look at a
    message as it arrives); a stop or an abort is recognised as ``read_object`` does."""
    try:
        found = read_object(payload)
    except CommandError as err:
        return Glance(None, None, err.reason)
    name, cid = found.fields.get("cmd"), echoable_id(found)
    if "cmd" in found.duplicates:
        return Glance(None, cid, "key 'cmd' given more than once with different values: ambiguous, refused")
    problem = cmd_problem(found.fields)
    if problem is not None:
        return Glance(None, cid, problem)
    return Glance(stop_word(name) or name, cid)


def peek(payload: bytes) -> tuple[str | None, str | None]:
    """``(cmd, id)`` of a payload (:func:`glance`), each None when it cannot be read."""
    found = glance(payload)
    return found.name, found.id
