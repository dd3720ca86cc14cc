"""Reading a ``<prefix>/cmd`` payload into one JSON object, refusing what
cannot be read unambiguously (no I/O).

A payload is refused (:class:`CommandError`) when it is over
``MAX_COMMAND_BYTES``, not UTF-8, empty, not JSON, nested too deeply for the
parser, or not an object. What is read but cannot be trusted is reported
beside the object for the command parser to judge: keys given twice (JSON
leaves the winner to the parser: the last one here, the first one elsewhere)
and text fields that cannot be written back as UTF-8 (a lone surrogate escape
such as ``"\\ud800"``), which no reply could echo.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from typing import Any

#: Largest command payload accepted (bytes); a command is a few dozen bytes.
MAX_COMMAND_BYTES = 4096
#: Deepest nesting of arrays and objects accepted; a command is one level deep.
#: Checked before parsing: the parser's own limit (RecursionError) moves with
#: ``sys.getrecursionlimit()``, which libraries in the same process may raise.
MAX_NESTING = 32

_STRING = re.compile(r'"(?:[^"\\]|\\.)*"')


class CommandError(ValueError):
    """A command payload that is refused. ``id`` is the correlation id when one
    could be read (a string), else None; ``reason`` is the text for the reply."""

    def __init__(self, reason: str, id: str | None = None):
        super().__init__(reason)
        self.reason = reason
        self.id = id


@dataclass(frozen=True)
class CommandObject:
    """The payload's object; ``duplicates``: keys given more than once (at any
    depth); ``unencodable``: top-level fields whose text is not valid Unicode."""

    fields: dict[str, Any]
    duplicates: tuple[str, ...] = ()
    unencodable: tuple[str, ...] = ()

    def problems(self) -> list[str]:
        """The reasons to refuse it, for the reply (empty: nothing to object to)."""
        out = [f"key {k!r} given more than once: ambiguous, refused" for k in self.duplicates]
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
    depth = deepest = 0
    for ch in _STRING.sub("", text):
        if ch in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif ch in "]}":
            depth -= 1
    return deepest


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


def read_object(payload: bytes | bytearray | str) -> CommandObject:
    """The JSON object of a payload, or CommandError whatever went wrong
    (size, encoding, syntax, nesting too deep for the parser, not an object)."""
    if isinstance(payload, (bytes, bytearray)):
        if len(payload) > MAX_COMMAND_BYTES:
            raise CommandError(f"payload too large: {len(payload)} bytes (at most {MAX_COMMAND_BYTES})")
        try:
            text = bytes(payload).decode("utf-8")
        except UnicodeDecodeError as err:
            raise CommandError(f"payload is not UTF-8: {err.reason} at byte {err.start}") from None
    else:
        text = payload
    if not text.strip():
        raise CommandError("payload is empty: expected a JSON object with 'cmd' and 'id'")
    if nesting(text) > MAX_NESTING:
        raise CommandError(f"payload is not a command: JSON nested too deeply (more than {MAX_NESTING} levels)")
    duplicates: list[str] = []

    def pairs(items: list[tuple[str, Any]]) -> dict[str, Any]:
        obj: dict[str, Any] = {}
        for key, value in items:
            if key in obj and key not in duplicates:
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
        raise CommandError(f"payload cannot be read: {type(err).__name__}") from None
    if not isinstance(obj, dict):
        raise CommandError(f"payload must be a JSON object, got {type_name(obj)}")
    unencodable = tuple(k for k, v in obj.items() if isinstance(v, str) and not encodable(v))
    return CommandObject(obj, tuple(duplicates), unencodable)


def peek(payload: bytes) -> tuple[str | None, str | None]:
    """``(cmd, id)`` of a payload without validating it, each None when it
    cannot be read as usable text: the first look at a message as it arrives."""
    try:
        found = read_object(payload)
    except CommandError:
        return None, None
    if "cmd" in found.duplicates:
        return None, None
    name, cid = found.fields.get("cmd"), found.fields.get("id")
    return (
        name if isinstance(name, str) else None,
        cid if isinstance(cid, str) and "id" not in found.unencodable and "id" not in found.duplicates else None,
    )
