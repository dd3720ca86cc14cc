"""How the report writes a matrix entry's name and an operating condition (the size a text with
subscripts prints at: orbitrig.analysis.figure_text, its names importable from here too).

A coefficient's key (``Kxx``, ``Kxy_1`` for the Omega^1 term, ``Zyx``) stays plain where a
machine reads it (CSV, JSON, the ROSS file); a figure writes it with a subscript in mathtext
(``K$_\\mathrm{xx}$``, ``K$_\\mathrm{xy,1}$``: upright, like the figure's other subscripts), the
HTML page with ``<sub>`` (``K<sub>xx</sub>``).

An operating condition (a stored point's settings, a catalog row's columns: ``spin``,
``recess_pressure``, ...) likewise: the store and the catalog keep plain SI numbers under plain
names; a figure writes its symbol in mathtext with its value at the edges' unit (rigunits):
``p$_\\mathrm{r}$ = 0.3 MPa``, ``\u03c9 = 1000 rpm``; the page its symbol with ``<sub>``.

A force on the journal (the tables' ``fx``, ``fy``) is F$_\\mathrm{x}$, F$_\\mathrm{y}$ in a figure,
F<sub>x</sub> on the page; a message the page shows lifts the phasor uncertainties' column names
it quotes unquoted (``u_x``, ``u_fy``, ``u_*``) to u<sub>x</sub>, u<sub>Fy</sub>, u<sub>*</sub>, and the
coherences' (``gamma2_xfx``, ``gamma2_*``) to \u03b3\u00b2<sub>xFx</sub>, \u03b3\u00b2<sub>*</sub>
(:func:`message_html`); the terminal and the data files keep the plain names.
"""

from __future__ import annotations

import html
import re
from collections.abc import Collection, Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from orbitrig.analysis.figure_text import (  # noqa: F401 - the figures' text sizes, imported from here
    lift_scripts,
    lifted_size,
    minus_signs,
    printed_size,
    script_scale,
    use_script_scale,
)
from orbitrig.load_systems import LMS
from reduction.columns import GAMMA2_COLUMNS
from rigunits import MPA, RPM, rpm_text

if TYPE_CHECKING:
    from orbitrig.store.stored_run import Settings

#: a matrix entry's key: matrix letter, entry, and the order of its Omega power term (none: 0)
_KEY = re.compile(r"([KCDZ])(xx|xy|yx|yy)(?:_(\d+))?")


def _parts(key: str) -> tuple[str, str] | None:
    """(letter, subscript) of a matrix entry's key: ("K", "xy,1") of ``Kxy_1``; None for another name."""
    m = _KEY.fullmatch(key)
    if m is None:
        return None
    letter, entry, order = m.groups()
    return letter, entry if order is None else f"{entry},{order}"


def sub_math(base: str, sub: str) -> str:
    """`base` with the subscript `sub` as a figure writes it (mathtext, upright): ``C$_\\mathrm{eff,xx}$``."""
    return f"{base}$_\\mathrm{{{sub}}}$"


def sub_html(base: str, sub: str) -> str:
    """`base` with the subscript `sub` as the HTML page writes it: ``C<sub>eff,xx</sub>``."""
    return f"{html.escape(base)}<sub>{html.escape(sub)}</sub>"


def entry_math(key: str) -> str:
    """`key` as a figure writes it (mathtext): ``K$_\\mathrm{xx}$``; a key that names no matrix entry as it is."""
    parts = _parts(key)
    return key if parts is None else sub_math(*parts)


def entry_html(key: str) -> str:
    """`key` as the HTML page writes it: ``K<sub>xx</sub>``; another name escaped as it is."""
    parts = _parts(key)
    return html.escape(key) if parts is None else sub_html(*parts)


def entry_marked(key: str) -> str:
    """`key` in the tables' markup (orbitrig.analysis.table_rows): ``K_{xx}``; another name as it is."""
    parts = _parts(key)
    return key if parts is None else f"{parts[0]}_{{{parts[1]}}}"


#: a force's symbol; its axis (x, y) is its subscript
FORCE = "F"


def force_math(axis: str) -> str:
    """The force along `axis` (x, y) as a figure writes it: ``F$_\\mathrm{x}$``."""
    return sub_math(FORCE, axis)


def force_html(axis: str) -> str:
    """The force along `axis` (x, y) as the page writes it: ``F<sub>x</sub>``."""
    return sub_html(FORCE, axis)


def force_channels() -> dict[str, tuple[str, str, str]]:
    """Each force channel (``fx_piezo``: the live feed's and the tables' name) as a page draws it:
    (symbol, subscript, load measuring system), ``("F", "x", "piezo")`` for F<sub>x</sub> piezo, as
    the report names the force and its system (the dashboard's plots receive them: its hello)."""
    return {f"f{axis}_{lms}": (FORCE, axis, str(lms)) for lms in LMS for axis in "xy"}


#: a motion/force pair of a coherence (gamma2_xfx ...): (displacement, force axis)
PAIRS = {pair: (pair[0], pair[2]) for pair in GAMMA2_COLUMNS}


def pair_math(pair: str) -> str:
    """A motion/force pair (``xfx``) as a figure writes it: ``x, F$_\\mathrm{x}$``."""
    motion, force = PAIRS[pair]
    return f"{motion}, {force_math(force)}"


def pair_html(pair: str) -> str:
    """A motion/force pair (``xfx``) as the page writes it: ``x, F<sub>x</sub>``."""
    motion, force = PAIRS[pair]
    return f"{motion}, {force_html(force)}"


#: a phasor uncertainty's or a coherence's column named in a message, not in quotes (a quoted name is
#: the file's column): its symbol's name (u, gamma2) and its subscript
_COLUMN = re.compile(rf"(?<![\w'`])(u|gamma2)_({'|'.join(PAIRS)}|fx|fy|x|y|\*)(?![\w'`])")
#: a column's symbol on the page: the coherence gamma2 is \u03b3\u00b2, as the report's coherence table heads it
_SYMBOLS = {"u": "u", "gamma2": "\u03b3\u00b2"}


def message_html(text: str) -> str:
    """A message (a fit's warning or note, a refusal) as the page shows it: escaped, the phasor
    uncertainties' and the coherences' columns it names unquoted subscripted (``u_x`` -> u<sub>x</sub>,
    ``u_fy`` -> u<sub>Fy</sub>, ``u_*`` -> u<sub>*</sub>, ``gamma2_xfx`` -> \u03b3\u00b2<sub>xFx</sub>)."""
    parts = _COLUMN.split(text)  # text, symbol, sub, text, symbol, sub, ..., text
    out = [html.escape(p) for p in parts[::3]]
    names = [sub_html(_SYMBOLS[sym], sub.replace("f", "F")) for sym, sub in zip(parts[1::3], parts[2::3])]
    return "".join(t + n for t, n in zip(out, [*names, ""]))


def message_marked(text: str) -> str:
    """A message in the tables' markup (orbitrig.analysis.table_rows): the columns it names
    subscripted as :func:`message_html` does (``u_x`` -> ``u_{x}``, ``gamma2_xfx`` -> ``\u03b3\u00b2_{xFx}``)."""
    return _COLUMN.sub(lambda m: f"{_SYMBOLS[m[1]]}_{{{m[2].replace('f', 'F')}}}", text)


@dataclass(frozen=True)
class Condition:
    """An operating condition as the paper writes it: in words, by its symbol, at its unit."""

    words: str  # "static eccentricity"
    symbol: str  # "\u03b5"
    sub: str  # its subscript, "" for none
    scale: float  # the column's value * scale: the value at the edges' unit (unit "": a ratio)
    unit: str = ""

    def math(self) -> str:
        """The symbol as a figure writes it: ``\u03b5$_\\mathrm{s}$``, ``\u03b2``."""
        return sub_math(self.symbol, self.sub) if self.sub else self.symbol

    def marked(self) -> str:
        """The symbol in the tables' markup (orbitrig.analysis.table_rows): ``\u03b5_{s}``."""
        return f"{self.symbol}_{{{self.sub}}}" if self.sub else self.symbol

    def html(self) -> str:
        """The symbol as the page writes it: ``\u03b5<sub>s</sub>``."""
        return sub_html(self.symbol, self.sub) if self.sub else html.escape(self.symbol)

    def text(self, value: float) -> str:
        """The value (the column's unit) at the edges' unit: ``1000 rpm``, ``0.3 MPa``, ``0.1``."""
        if self.unit == "rpm":  # rigunits' rpm text: no float noise of the rad/s round trip
            return rpm_text(value * self.scale * RPM)
        return f"{value * self.scale:g}" + (f" {self.unit}" if self.unit else "")


#: the operating conditions by the column (of a stored point's settings, a catalog row, a
#: predicted CSV) that holds them: spin in rad/s or in rpm, recess pressure in Pa
CONDITIONS = {
    "spin": Condition("spin", "\u03c9", "", 1 / RPM, "rpm"),
    "spin_rpm": Condition("spin", "\u03c9", "", 1.0, "rpm"),
    "recess_pressure": Condition("recess pressure", "p", "r", 1 / MPA, "MPa"),
    "pressure_ratio": Condition("pressure ratio", "\u03b2", "", 1.0),
    "static_eccentricity": Condition("static eccentricity", "\u03b5", "s", 1.0),
    "dynamic_eccentricity": Condition("dynamic eccentricity", "\u03b5", "d", 1.0),
}


def condition_label(column: str) -> str:
    """An axis label naming the condition of `column` (mathtext): ``static eccentricity
    \u03b5$_\\mathrm{s}$``, ``spin \u03c9 [rpm]``."""
    c = CONDITIONS[column]
    return f"{c.words} {c.math()}" + (f" [{c.unit}]" if c.unit else "")


def condition_math(column: str, value: float | None) -> str:
    """The condition `column` at `value` (the column's unit) as a figure writes it (mathtext):
    ``p$_\\mathrm{r}$ = 0.3 MPa``; ``\u03b2 = ?`` for a value not stored."""
    c = CONDITIONS[column]
    return f"{c.math()} = {'?' if value is None else c.text(value)}"


def _point(s: Settings) -> dict[str, float]:
    """A stored point's conditions in the order its title gives them: column -> value (SI)."""
    return {
        "spin": s.spin,
        "dynamic_eccentricity": s.dynamic_eccentricity,
        "static_eccentricity": s.static_eccentricity,
        "recess_pressure": s.recess_pressure,
        "pressure_ratio": s.pressure_ratio,
    }


def operating_point_math(s: Settings, columns: Collection[str] | None = None) -> str:
    """A stored point's settings as its figures' titles give them (mathtext): ``\u03c9 = 1000 rpm,
    \u03b5$_\\mathrm{d}$ = 0.05, \u03b5$_\\mathrm{s}$ = 0.1, p$_\\mathrm{r}$ = 0.3 MPa, \u03b2 = 0.4``;
    `columns`: only those conditions (:func:`varied`), in the same order."""
    point = _point(s)
    return ", ".join(condition_math(c, v) for c, v in point.items() if columns is None or c in columns)


def operating_point_marked(s: Settings) -> str:
    """A stored point's settings as :func:`operating_point_math`, in the tables' markup."""
    return ", ".join(f"{CONDITIONS[c].marked()} = {CONDITIONS[c].text(v)}" for c, v in _point(s).items())


def varied(points: Iterable[Settings]) -> tuple[list[str], list[str]]:
    """(the conditions whose values differ among the stored points `points`: what tells them apart,
    those all of them share), each as columns in the titles' order."""
    rows = [_point(s) for s in points]
    differ = differing_conditions(row.items() for row in rows)
    return differ, [c for c in (rows[0] if rows else ()) if c not in differ]


def differing_conditions(sets: Iterable[Iterable[tuple[str, Any]]]) -> list[str]:
    """The columns, in the order first met, holding more than one value among `sets` (each a set
    of conditions, (column, value) pairs): what tells the sets apart in a label."""
    values: dict[str, set] = {}
    for conditions in sets:
        for column, value in conditions:
            values.setdefault(column, set()).add(value)
    return [column for column, seen in values.items() if len(seen) > 1]


def operating_point_html(s: Settings) -> str:
    """The same as the page writes it: ``\u03c9 = 1000 rpm, \u03b5<sub>d</sub> = 0.05, ...``."""
    return ", ".join(f"{CONDITIONS[c].html()} = {html.escape(CONDITIONS[c].text(v))}" for c, v in _point(s).items())
