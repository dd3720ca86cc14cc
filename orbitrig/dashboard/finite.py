"""What comes from the broker made safe for the page once, where the session reads it: a payload's NaN and
infinities (JSON has none: a publisher other than the rig service, or an older one, may still write ``NaN``,
``Infinity`` or ``1e999``, which Python's reader takes) become null, and the fields replaced are named, so
that the page says the value was not a number rather than not known. The rig service itself never publishes
them (orbitrig.service.protocol.dumps writes a non-finite float as null).
"""

from __future__ import annotations

import json
import math
import re
from typing import Any

#: fields named at most per payload (a payload of NaN arrays would name thousands): the rest are counted
NAMED = 20

#: a number that may overflow to infinity: an exponent of three digits (``1e999``), or 200 digits in a row (a float
#: written without one, ``1000...0.0``, or with one of two digits, needs 210 before its point to pass 1.8e308)
_LARGE_NUMBER = re.compile(rb"[eE]\+?[0-9]{3}|[0-9]{200}")


def read_finite(raw: bytes | bytearray | str) -> tuple[Any, list[str]]:
    """The JSON value of a message's payload made finite (:func:`made_finite`). A payload is walked only when its
    text has ``NaN`` or ``Infinity`` or a number that may be too large (_LARGE_NUMBER; a result of 2 kB: a few µs
    to look, not 40 µs to walk). ValueError, RecursionError: not JSON, or nested too deep."""
    data = json.loads(raw)
    text = raw.encode() if isinstance(raw, str) else raw
    maybe = b"NaN" in text or b"Infinity" in text or _LARGE_NUMBER.search(text) is not None
    return made_finite(data) if maybe else (data, [])


def made_finite(payload: Any) -> tuple[Any, list[str]]:
    """``payload`` with each non-finite float null, and the paths of the fields replaced (``a.b.0.c``: the
    field ``c`` of the first element of ``a.b``; at most NAMED, then ``"... and N more"``). ``payload`` itself
    is returned when nothing was replaced (the common case copies nothing)."""
    replaced: list[str] = []
    out = _finite(payload, "", replaced)
    if len(replaced) > NAMED:
        replaced[NAMED:] = [f"... and {len(replaced) - NAMED} more"]
    return out, replaced


def _finite(value: Any, path: str, replaced: list[str]) -> Any:
    """``value`` (at ``path``) with its non-finite floats null, each one's path in ``replaced``; the same object
    when none was (a path is written only for a container or a field replaced: a result's numbers are many)."""
    if isinstance(value, float):
        if math.isfinite(value):
            return value
        replaced.append(path)
        return None
    if not isinstance(value, (dict, list)):
        return value
    before = len(replaced)
    pairs = value.items() if isinstance(value, dict) else enumerate(value)
    items = [(k, v if _plain(v) else _finite(v, f"{path}.{k}" if path else str(k), replaced)) for k, v in pairs]
    if len(replaced) == before:
        return value
    return dict(items) if isinstance(value, dict) else [v for _, v in items]


def _plain(value: Any) -> bool:
    """A leaf that stays as it is: not a container, not a non-finite float."""
    return not isinstance(value, (dict, list)) and not (isinstance(value, float) and not math.isfinite(value))
