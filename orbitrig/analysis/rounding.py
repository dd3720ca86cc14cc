"""Numbers as a person reads them in a table: rounded to significant digits, or a value beside
its uncertainty with as many digits as the uncertainty supports (standard library only: the
command line imports it without numpy)."""

from __future__ import annotations

import math
import re

PLUS_MINUS = "\u00b1"
MINUS = "\u2212"
#: an ASCII hyphen standing for a minus sign: before a number ('-0.35', '[-3.58, -3.42]', '^-1'),
#: not inside a word, a number, a date or a range ('kcd11-power', '2026-12-07', '0000-0004', '1e-05')
_HYPHEN_MINUS = re.compile(r"(?<![\w.\-\u2212])-(?=\.?\d)")


def number(v: float | None, full: bool = False, digits: int = 4) -> str:
    """A number as a table shows it: rounded to `digits` significant digits for reading, or
    `full` (CSV) the shortest decimal that reads back as the same double (repr); a missing or
    non-finite number is '-' (CSV: an empty cell)."""
    if v is None or not math.isfinite(v):
        return "" if full else "-"
    return repr(float(v)) if full else f"{v:.{digits}g}"


def orbit_frequency(hz: float | None) -> str:
    """An orbit frequency as the report states it, in every title, panel and table: to 4
    significant digits with its unit, '3.333 Hz', '20 Hz' (:func:`number`); '- Hz' when missing."""
    return f"{number(hz, digits=4)} Hz"


def speed_ratio(r: float | None) -> str:
    """A ratio of speeds (Omega/omega) as the report states it, in its figures and tables: to 3
    significant digits, '0.732', '1.2' (:func:`number`); '-' when missing."""
    return number(r, digits=3)


def uncertainty_decimals(u: float | None) -> int | None:
    """The decimal an uncertainty `u` rounded to 2 significant digits ends at: 0.1234 -> 2 (0.12),
    0.0996 -> 2 (0.10), 1234 -> -2 (1200); None for a missing, non-finite or non-positive `u`."""
    if u is None or not math.isfinite(u) or u <= 0:
        return None
    decimals = 1 - math.floor(math.log10(u))
    return 1 - math.floor(math.log10(round(u, decimals)))  # 0.0996 rounds up to 0.10


def at_decimals(v: float | None, decimals: int | None) -> str:
    """`v` rounded to `decimals` places (< 0: to tens, hundreds ...; None: 4 significant digits,
    as :func:`number`); '-' when missing or not finite; never '-0.00'."""
    if v is None or not math.isfinite(v) or decimals is None:
        return number(v)
    rounded = round(v, decimals) + 0.0  # -0.001 at 2 decimals: 0.00, not -0.00
    return f"{rounded:.{max(decimals, 0)}f}"


def with_uncertainty(v: float | None, u: float | None) -> str:
    """'12.35 ± 0.12': the uncertainty `u` to 2 significant digits and the value `v` rounded to
    the same decimal (both in one unit); without a usable `u` the value to 4 significant digits
    and '± -'."""
    decimals = uncertainty_decimals(u)
    return f"{at_decimals(v, decimals)} {PLUS_MINUS} {at_decimals(u, decimals) if decimals is not None else '-'}"


def typeset_minus(text: str) -> str:
    """`text` for a person to read (the report's page and figures), each ASCII hyphen standing for
    a minus sign written as the minus sign U+2212, as print sets it: '-0.35 deg' -> '−0.35 deg';
    outside mathtext's $...$ (its own minus there). Files a program reads (CSV, JSON) keep ASCII."""
    if "-" not in text:
        return text
    parts = text.split("$")
    parts[::2] = [_HYPHEN_MINUS.sub(MINUS, p) for p in parts[::2]]
    return "$".join(parts)
