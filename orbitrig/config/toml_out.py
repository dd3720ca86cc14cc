"""TOML text of a calibration record (strings, numbers, booleans, lists of them, nested tables).

Plain values first, then each table under its dotted header, so the output reads back with
tomllib to the same data. Floats keep 10 significant digits.
"""

from __future__ import annotations

import json
import math


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            raise ValueError(f"TOML record: {v} is not a finite number")
        text = f"{v:.10g}"
        return text if any(c in text for c in ".en") else text + ".0"
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    raise TypeError(f"TOML record: cannot write {type(v).__name__}")


def render(data: dict, header: str = "", comments: dict[str, str] | None = None) -> str:
    """TOML text of ``data``; ``header`` a comment block on top; ``comments`` a trailing comment
    per key path ("reference.uncertainty_pct")."""
    lines = [f"# {line}".rstrip() for line in header.splitlines()] if header else []
    _table(data, (), lines, comments or {})
    return "\n".join(lines).strip("\n") + "\n"


def _table(data: dict, path: tuple[str, ...], lines: list[str], comments: dict[str, str]) -> None:
    plain = {k: v for k, v in data.items() if not isinstance(v, dict)}
    tables = {k: v for k, v in data.items() if isinstance(v, dict)}
    if path and plain:
        lines += ["", "[" + ".".join(path) + "]"]
    for key, v in plain.items():
        note = comments.get(".".join(path + (key,)))
        lines.append(f"{key} = {_value(v)}" + (f"  # {note}" if note else ""))
    for key, sub in tables.items():
        _table(sub, path + (key,), lines, comments)
