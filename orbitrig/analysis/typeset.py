"""How the report writes a matrix entry's name and an operating condition, and the size a text
with subscripts is printed at.

A coefficient's key (``Kxx``, ``Kxy_1`` for the Omega^1 term, ``Zyx``) stays plain where a
machine reads it (CSV, JSON, the ROSS file); a figure writes it with a subscript in mathtext
(``K$_\\mathrm{xx}$``, ``K$_\\mathrm{xy,1}$``: upright, like the figure's other subscripts), the
HTML page with ``<sub>`` (``K<sub>xx</sub>``). mathtext draws a subscript smaller than its text
(:func:`script_scale`): the report's figures draw it at their smallest text size over their body
text's (:func:`use_script_scale`, 7/7.5, not mathtext's 0.7), so a label with subscripts keeps the
body size; :func:`lift_scripts` enlarges a text with subscripts set smaller (a legend entry, a
tick label at the smallest size) until its smallest glyph prints at the smallest text size.

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
import math
import re
from collections.abc import Collection, Iterable
from dataclasses import dataclass
from functools import cache, lru_cache
from typing import TYPE_CHECKING, Any

from orbitrig.analysis.rounding import typeset_minus
from orbitrig.load_systems import LMS
from reduction.columns import GAMMA2_COLUMNS
from rigunits import MPA, RPM, rpm_text

if TYPE_CHECKING:  # matplotlib is imported where a figure's text is measured: the dashboard reads the names alone
    from matplotlib.figure import Figure
    from matplotlib.text import Text

    from orbitrig.store.stored_run import Settings

#: a matrix entry's key: matrix letter, entry, and the order of its Omega power term (none: 0)
_KEY = re.compile(r"([KCDZ])(xx|xy|yx|yy)(?:_(\d+))?")


@cache
def _parser() -> Any:
    from matplotlib.mathtext import MathTextParser

    return MathTextParser("path")


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


def printed_size(text: str, size: float) -> float:
    """The smallest glyph (pt) of `text` drawn at `size` pt: a subscript's or superscript's in mathtext
    (each line on its own, as matplotlib lays out a text of several lines)."""
    from matplotlib.cbook import is_math_text

    lines = [line for line in text.split("\n") if is_math_text(line)]
    return min((_smallest_glyph(line, size) for line in lines), default=size)


def _smallest_glyph(line: str, size: float) -> float:
    """The smallest glyph (pt) of the mathtext `line` drawn at `size` pt (`size` with none)."""
    return size * _smallest_scale(line)


#: a line whose every mathtext part is one upright subscript after its letter (``ε$_\\mathrm{d}$``,
#: ``C$_\\mathrm{eff,xx}$``; a name's at most 24 letters, digits, commas, dots, signs, spaces): its
#: smallest glyph is a subscript's
_PLAIN_SUBSCRIPTS = re.compile(r"[^$\\{}_^]*(?:\$_\\mathrm\{[A-Za-z0-9][A-Za-z0-9,.+\- ]{0,23}\}\$[^$\\{}_^]*)+")


@lru_cache(maxsize=4096)
def _smallest_scale(line: str) -> float:
    """The smallest glyph of the mathtext `line` over its size: mathtext scales every glyph with
    the size (a subscript by :func:`script_scale`), so one parse serves every size the line is measured at (a
    label is measured at its size and at the size it is lifted to); the same labels recur in
    every figure of a report, and each parse costs about 10 ms. A line of plain subscripts
    (_PLAIN_SUBSCRIPTS: the report's conditions and coefficients, in legend entries that change
    with every point) has a subscript's, found without a parse of its own."""
    if _PLAIN_SUBSCRIPTS.fullmatch(line) and line != _A_SUBSCRIPT:
        return _smallest_scale(_A_SUBSCRIPT)
    from matplotlib.font_manager import FontProperties

    size = 10.0
    glyphs = _parser().parse(line, dpi=72, prop=FontProperties(size=size)).glyphs
    return min((float(g[1]) for g in glyphs), default=size) / size


_A_SUBSCRIPT = "x$_\\mathrm{x}$"


@cache
def script_scale() -> float:
    """How much smaller mathtext draws a subscript than its text (:func:`use_script_scale`'s, as measured)."""
    return printed_size(_A_SUBSCRIPT, 10.0) / 10.0


def use_script_scale(scale: float) -> None:
    """Draw every later mathtext subscript of this process at `scale` of its text's size (the report's:
    its smallest text size over its body text's, so that a label set at the body size prints its
    subscripts at the smallest size and is not enlarged beside the texts without). mathtext draws
    them at 0.7 (TeX's script size) and has no setting for it: its module's constant is set before
    a figure's text is laid out (plots.use_style sets it: on import, and with each style), and the
    layouts kept at the scale before (matplotlib's, these measurements') are dropped. A matplotlib
    without that constant or cache keeps its own scale, and :func:`lift_scripts` lifts such labels."""
    from matplotlib import _mathtext
    from matplotlib.mathtext import MathTextParser

    parsed = getattr(MathTextParser, "_parse_cached", None)  # private: absent in some release, maybe
    if not hasattr(_mathtext, "SHRINK_FACTOR") or parsed is None:
        return
    if _mathtext.SHRINK_FACTOR != scale:
        _mathtext.SHRINK_FACTOR = scale
        parsed.cache_clear()  # matplotlib's 50 layouts
        _smallest_scale.cache_clear()
        script_scale.cache_clear()


def _points(t: Text) -> float:
    """`t`'s font size (pt)."""
    return float(t.get_fontproperties().get_size_in_points())


def lifted_size(text: str, size: float, smallest: float) -> float:
    """The size (pt, to the next 0.1 pt up) `text` set at `size` pt needs for its smallest glyph
    to print at `smallest` pt at least (`size` when it does)."""
    printed = printed_size(text, size)
    return size if printed >= smallest else math.ceil(size * smallest / printed * 10 - 1e-6) / 10


def _lifted(t: Text, smallest: float) -> float:
    """The size (pt) `t` needs for its smallest glyph to print at `smallest` pt at least."""
    return lifted_size(t.get_text(), _points(t), smallest)


def _roles(fig: Figure) -> list[list[Text]]:
    """The texts of `fig` drawn alike, which keep one size: the panels' titles, the panels' axis
    labels, each legend's entries; every other text on its own."""
    titles = [ax.title for ax in fig.axes]  # the report sets only the centred title
    labels = [axis.label for ax in fig.axes for axis in (ax.xaxis, ax.yaxis)]
    legends = [lg for lg in (*fig.legends, *(ax.get_legend() for ax in fig.axes)) if lg is not None]
    entries = [list(lg.get_texts()) for lg in legends]
    grouped = {id(t) for t in (*titles, *labels, *(t for group in entries for t in group))}
    alone = [[t] for t in _texts(fig) if id(t) not in grouped]
    return [titles, labels, *entries, *alone]


def _texts(fig: Figure) -> list[Text]:
    """Every Text of `fig`, as ``fig.findobj(Text)`` finds them (its artists and theirs, in another
    order) without the list findobj joins for every artist of the figure. An axis gives its label,
    offset text and the labels of the ticks it has: its own children would be its ticks at the
    locator's positions, found again (and made) on every walk: most of a figure's lifting."""
    from matplotlib.axis import Axis
    from matplotlib.text import Text

    found: list[Text] = []
    todo: list[Any] = [fig]
    while todo:
        artist = todo.pop()
        if isinstance(artist, Text):
            found.append(artist)
        elif isinstance(artist, Axis):
            ticks = (*artist.majorTicks, *artist.minorTicks)
            found.extend((artist.label, artist.offsetText, *(t for k in ticks for t in (k.label1, k.label2))))
            continue
        todo.extend(artist.get_children())
    return found


def minus_signs(fig: Figure) -> None:
    """Every text of `fig` with the ASCII hyphens that stand for minus signs as U+2212
    (rounding.typeset_minus: a title's 'phase −0.51 deg', as the tick labels' minus)."""
    for t in _texts(fig):
        text = t.get_text()
        if "-" in text and (signed := typeset_minus(text)) != text:
            t.set_text(signed)


def lift_scripts(fig: Figure, smallest: float) -> None:
    """Every text of `fig` whose smallest glyph would print under `smallest` pt (its subscripts)
    enlarged until it does not: a text with subscripts at `smallest` / :func:`script_scale`, and the
    texts drawn alike with it (the other panels' titles, axis labels, entries of its legend) to the same size."""
    from matplotlib.cbook import is_math_text

    for group in _roles(fig):
        needs = [t for t in group if t.get_text() and is_math_text(t.get_text())]
        size = max((_lifted(t, smallest) for t in needs), default=0.0)
        for t in (t for t in group if _points(t) < size):
            t.set_fontsize(size)
