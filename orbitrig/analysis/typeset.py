"""How the report writes a matrix entry's name, and the size a text with subscripts is printed at.

A coefficient's key (``Kxx``, ``Kxy_1`` for the Omega^1 term, ``Zyx``) stays plain where a
machine reads it (CSV, JSON, the ROSS file); a figure writes it with a subscript in mathtext
(``K$_\\mathrm{xx}$``, ``K$_\\mathrm{xy,1}$``: upright, like the figure's other subscripts), the
HTML page with ``<sub>`` (``K<sub>xx</sub>``). mathtext draws a subscript smaller than its text
(:func:`script_scale`, about 0.7), so :func:`lift_scripts` enlarges a figure's texts with
subscripts until their smallest glyph is printed at the smallest text size.
"""

from __future__ import annotations

import html
import math
import re
from functools import cache

from matplotlib.cbook import is_math_text
from matplotlib.figure import Figure
from matplotlib.font_manager import FontProperties
from matplotlib.mathtext import MathTextParser
from matplotlib.text import Text

#: a matrix entry's key: matrix letter, entry, and the order of its Omega power term (none: 0)
_KEY = re.compile(r"([KCDZ])(xx|xy|yx|yy)(?:_(\d+))?")

_PARSER = MathTextParser("path")


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


def printed_size(text: str, size: float) -> float:
    """The smallest glyph (pt) of `text` drawn at `size` pt: a subscript's or superscript's in mathtext."""
    if not is_math_text(text):
        return size
    glyphs = _PARSER.parse(text, dpi=72, prop=FontProperties(size=size)).glyphs
    return min((g[1] for g in glyphs), default=size)


@cache
def script_scale() -> float:
    """How much smaller mathtext draws a subscript than its text (matplotlib's, about 0.7)."""
    return printed_size("x$_\\mathrm{x}$", 10.0) / 10.0


def _points(t: Text) -> float:
    """`t`'s font size (pt)."""
    return float(t.get_fontproperties().get_size_in_points())


def _lifted(t: Text, smallest: float) -> float:
    """The size (pt, to the next 0.1 pt up) `t` needs for its smallest glyph to print at `smallest` pt at least."""
    size = _points(t)
    printed = printed_size(t.get_text(), size)
    return size if printed >= smallest else math.ceil(size * smallest / printed * 10 - 1e-6) / 10


def _roles(fig: Figure) -> list[list[Text]]:
    """The texts of `fig` drawn alike, which keep one size: the panels' titles, the panels' axis
    labels, each legend's entries; every other text on its own."""
    titles = [ax.title for ax in fig.axes]  # the report sets only the centred title
    labels = [axis.label for ax in fig.axes for axis in (ax.xaxis, ax.yaxis)]
    legends = [lg for lg in (*fig.legends, *(ax.get_legend() for ax in fig.axes)) if lg is not None]
    entries = [list(lg.get_texts()) for lg in legends]
    grouped = {id(t) for t in (*titles, *labels, *(t for group in entries for t in group))}
    alone = [[t] for t in fig.findobj(Text) if id(t) not in grouped and isinstance(t, Text)]
    return [titles, labels, *entries, *alone]


def lift_scripts(fig: Figure, smallest: float) -> None:
    """Every text of `fig` whose smallest glyph would print under `smallest` pt (its subscripts)
    enlarged until it does not: a text with subscripts at `smallest` / :func:`script_scale`, and the
    texts drawn alike with it (the other panels' titles, axis labels, entries of its legend) to the same size."""
    for group in _roles(fig):
        needs = [t for t in group if t.get_text() and is_math_text(t.get_text())]
        size = max((_lifted(t, smallest) for t in needs), default=0.0)
        for t in (t for t in group if _points(t) < size):
            t.set_fontsize(size)
