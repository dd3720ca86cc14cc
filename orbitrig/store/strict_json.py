"""JSON objects read strictly: a key given twice is refused (readers differ in which of the two
counts; `json.loads` keeps the last). The run header and the ROSS export are read with it."""

from __future__ import annotations

from typing import Any


def once_each(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """`json.loads`'s ``object_pairs_hook``: the object, or ValueError naming a key given twice."""
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise ValueError(f"key {key!r} given twice")
        out[key] = value
    return out
