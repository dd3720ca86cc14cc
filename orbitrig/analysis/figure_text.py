"""The size a figure's texts print at: the smallest glyph of a text with subscripts, the
scale mathtext draws a subscript at, the lifting of a text whose subscripts would print under
the smallest text size, and the minus signs of a figure's texts.

mathtext draws a subscript smaller than its text (:func:`script_scale`): the report's figures draw
it at their smallest text size over their body text's (:func:`use_script_scale`, 7/7.5, not
mathtext's 0.7), so a label with subscripts keeps the body size; :func:`lift_scripts` enlarges a
text with subscripts set smaller (a legend entry, a tick label at the smallest size) until its
smallest glyph prints at the smallest text size. How the names themselves are written:
orbitrig.analysis.typeset.
"""

from __future__ import annotations

import math
import re
from functools import cache, lru_cache
from typing import TYPE_CHECKING, Any

from orbitrig.analysis.rounding import typeset_minus

if TYPE_CHECKING:  # matplotlib is imported where a figure's text is measured
    from matplotlib.figure import Figure
    from matplotlib.text import Text


@cache
def _parser() -> Any:
    from matplotlib.mathtext import MathTextParser

    return MathTextParser("path")


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
