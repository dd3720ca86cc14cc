"""`--where` filters: a small grammar parsed into SQLAlchemy expressions, never SQL text.

    filter     := condition ("and" condition)*
    condition  := COLUMN OP VALUE
    OP         := "=" | "==" | "!=" | "<" | "<=" | ">" | ">="
    VALUE      := a number, true/false, or text (bare word or in '...' / "...")

COLUMN is one of the catalog's columns (orbitrig.catalog.schema); the value is bound as
a parameter of the column's type. Example: ``static_eccentricity > 0.1 and lms = piezo``.
On a number column a stored value within 1e-9 (relative) of the value written is equal to it
(9 significant digits, as `compare` groups conditions: 1.001 MPa is 1000999.9999999999 Pa).

The text is cut into tokens (bare words, quoted texts, operators, parentheses) and read
token by token; anything outside the grammar (``or``, ``not``, parentheses, a character
no token takes, a token out of place, a value of the wrong type) raises CatalogUsageError
naming it, as does a column holding JSON as text (``orbit_hz``, ``coefficients_json``), which a
comparison would match only as text. Bare words are letters, digits and ``_ . : + - / @``; quote any other text.
``and``, ``or`` and ``not`` are words of the grammar: quoted they are text.
"""

from __future__ import annotations

import operator
import re
from dataclasses import dataclass
from enum import Enum

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
#: words of a grammar richer than this one, refused with a hint rather than read as text
_REFUSED_WORDS = {
    "or": "not part of the grammar: conditions are joined with 'and' only",
    "not": "not part of the grammar: use != or the opposite comparison",
}
#: how a message names the values a column of each type takes
_TAKES = {Boolean: "true or false", Integer: "an integer", Float: "a number"}
_COLUMN_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
#: the columns holding JSON as text, which a comparison would only match as text: refused, saying how
_JSON_COLUMNS = {
    "orbit_hz": "a JSON list of frequencies stored as text, which --where does not compare (orbit_hz = 5 would "
    "match nothing); select the points by another column (spin, spin_rpm, label, n_frequencies) or filter the "
    "list in `orbitrig catalog export --format json`, where it is a list",
    "coefficients_json": "a JSON object stored as text, which --where does not compare; the constant "
    "coefficients and their U have columns of their own (Kxx ... Dyy, Kxx_U ... Dyy_U)",
}


class Kind(Enum):
    """The kinds of token of a filter."""

    WORD = re.compile(r"[\w.:+\-/@]+")
    QUOTED = re.compile(r"'([^']*)'|\"([^\"]*)\"")
    OP = re.compile(r"==|!=|<=|>=|=|<|>")
    PAREN = re.compile(r"[()]")


@dataclass(frozen=True)
class Token:
    kind: Kind
    text: str  # as the value (quotes removed)
    shown: str  # as written

    def keyword(self) -> str | None:
        """'and', 'or', 'not' (any case) for a bare word of the grammar, else None."""
        word = self.text.lower()
        return word if self.kind is Kind.WORD and word in ("and", *_REFUSED_WORDS) else None


def tokens(text: str) -> list[Token]:
    """The tokens of ``text``; CatalogUsageError names a character no token takes."""
    out, pos = [], 0
    while pos < len(text):
        if text[pos].isspace():
            pos += 1
            continue
        for kind in Kind:
            m = kind.value.match(text, pos)
            if m:
                value = next((g for g in m.groups() if g is not None), "") if kind is Kind.QUOTED else m.group()
                out.append(Token(kind, value, m.group()))
                pos = m.end()
                break
        else:
            what = "an unclosed quote" if text[pos] in "'\"" else f"{text[pos]!r}"
            raise CatalogUsageError(f"--where {text!r}: cannot parse {what} at character {pos + 1}")
    return out


def parse_where(text: str) -> ColumnElement | None:
    """The filter ``text`` as an expression on the ``fits`` table (None: no filter).
    Raises CatalogUsageError naming the offending part."""
    words = tokens(text)
    if not words:
        return None
    conditions, at = [], 0
    while True:
        conditions.append(_condition(words[at : at + 3], text))
        at += 3
        if at == len(words):
            break
        if words[at].keyword() != "and":
            done = " ".join(t.shown for t in words[at - 3 : at])
            raise CatalogUsageError(
                f"--where {text!r}: found {_found(words[at])} after {done!r} where 'and' or the end was expected"
            )
        at += 1
    return and_(*conditions) if len(conditions) > 1 else conditions[0]


def _found(token: Token | None) -> str:
    """How a message names a token out of place (None: the end of the filter)."""
    if token is None:
        return "the end of the filter"
    if token.kind is Kind.PAREN:
        return f"{token.shown!r} (parentheses are not part of the grammar)"
    keyword = token.keyword()
    return f"{token.shown!r} ({_REFUSED_WORDS[keyword]})" if keyword in _REFUSED_WORDS else repr(token.shown)


def _condition(part: list[Token], text: str) -> ColumnElement:
    """``COLUMN OP VALUE`` from the three tokens ``part`` (fewer at the end of the filter)."""
    name, op, raw = (part + [None, None, None])[:3]
    if name is None or name.kind is not Kind.WORD or name.keyword() or not _COLUMN_NAME.fullmatch(name.text):
        raise CatalogUsageError(f"--where {text!r}: found {_found(name)} where a column name was expected")
    if name.text not in fits.c or name.text == "id":
        columns = ", ".join(c for c in fits.c.keys() if c != "id")
        raise CatalogUsageError(f"--where {text!r}: unknown column {name.text!r}; columns: {columns}")
    if name.text in _JSON_COLUMNS:
        raise CatalogUsageError(f"--where {text!r}: column {name.text!r} holds {_JSON_COLUMNS[name.text]}")
    if op is None or op.kind is not Kind.OP:
        raise CatalogUsageError(
            f"--where {text!r}: found {_found(op)} after {name.text!r} "
            f"where an operator ({' '.join(_OPERATORS)}) was expected"
        )
    if raw is None or raw.kind not in (Kind.WORD, Kind.QUOTED) or raw.keyword():
        raise CatalogUsageError(
            f"--where {text!r}: found {_found(raw)} after '{name.text} {op.text}' where a value was expected"
        )
    column = fits.c[name.text]
    value = _value(column, raw.text, text)
    if isinstance(column.type, Float):
        return _near(column, op.text, value)
    return _OPERATORS[op.text](column, value)


#: relative difference within which a stored number equals the number written (9 significant
#: digits, as compare's conditions: 1.001 MPa is stored as 1000999.9999999999 Pa)
REL_TOL = 1e-9


def _near(column, op: str, value: float) -> ColumnElement:
    """``column OP value`` on a number column, a stored value within REL_TOL of ``value``
    counting as equal to it (``=`` matches it, ``<`` does not, ``<=`` does)."""
    tol = abs(value) * REL_TOL
    low, high = value - tol, value + tol
    if op in ("=", "=="):
        return column.between(low, high)
    if op == "!=":
        return ~column.between(low, high)
    return {"<": column < low, "<=": column <= high, ">": column > high, ">=": column >= low}[op]


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
        wanted = next(words for sql_type, words in _TAKES.items() if isinstance(kind, sql_type))
        raise CatalogUsageError(f"--where {text!r}: column {column.name!r} takes {wanted}, not {raw!r}") from None
    return raw
