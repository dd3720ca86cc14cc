"""`--where` filters: a small grammar parsed into SQLAlchemy expressions, never SQL text.

    filter     := condition ("and" condition)*
    condition  := COLUMN OP VALUE
    OP         := "=" | "==" | "!=" | "<" | "<=" | ">" | ">="
    VALUE      := a number, true/false, or text (bare word or in '...' / "...")

COLUMN is one of the catalog's columns (orbitrig.catalog.schema); the value is bound as
a parameter of the column's type. Example: ``static_eccentricity > 0.1 and lms = piezo``.
"""

from __future__ import annotations

import operator
import re
import shlex

from sqlalchemy import Boolean, Float, Integer, and_
from sqlalchemy.sql.elements import ColumnElement

from orbitrig.catalog.errors import CatalogUsageError
from orbitrig.catalog.schema import fits

_OPERATORS = {
    "=": operator.eq,
    "==": operator.eq,
    "!=": operator.ne,
    "<": operator.lt,
    "<=": operator.le,
    ">": operator.gt,
    ">=": operator.ge,
}
_CONDITION = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)(==|!=|<=|>=|=|<|>)(.+)$")


def parse_where(text: str) -> ColumnElement | None:
    """The filter ``text`` as an expression on the ``fits`` table (None: no filter).
    Raises CatalogUsageError naming the offending part."""
    if not text.strip():
        return None
    try:
        words = shlex.split(text)
    except ValueError as err:
        raise CatalogUsageError(f"--where {text!r}: {err}") from None
    conditions, current = [], []
    for word in words + ["and"]:
        if word.lower() == "and":
            if not current:
                raise CatalogUsageError(f"--where {text!r}: 'and' without a condition on both sides")
            conditions.append(_condition("".join(current), text))
            current = []
        else:
            current.append(word)
    return and_(*conditions) if len(conditions) > 1 else conditions[0]


def _condition(part: str, text: str) -> ColumnElement:
    m = _CONDITION.match(part)
    if m is None:
        raise CatalogUsageError(
            f"--where {text!r}: {part!r} is not 'column op value' (op one of {' '.join(_OPERATORS)})"
        )
    name, op, raw = m.groups()
    if name not in fits.c or name == "id":
        raise CatalogUsageError(
            f"--where {text!r}: unknown column {name!r}; columns: {', '.join(c for c in fits.c.keys() if c != 'id')}"
        )
    column = fits.c[name]
    return _OPERATORS[op](column, _value(column, raw, text))


def _value(column, raw: str, text: str):
    kind = column.type
    try:
        if isinstance(kind, Boolean):
            if raw.lower() not in ("true", "false", "1", "0"):
                raise ValueError(raw)
            return raw.lower() in ("true", "1")
        if isinstance(kind, Integer):
            return int(raw)
        if isinstance(kind, Float):
            return float(raw)
    except ValueError:
        raise CatalogUsageError(
            f"--where {text!r}: column {column.name!r} takes a {kind.python_type.__name__}, not {raw!r}"
        ) from None
    return raw
