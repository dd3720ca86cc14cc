"""Report figures narrower than NARROW_WIDTH (5 in; a journal's single column is 85 mm, 3.35 in) at the same text
size (7.5 pt): at most NARROW_COLUMNS (two) columns of panels, each at least PANEL_WIDTH wide, so
one column below 3.2 in (a logical row of four entries becomes two rows of two; below 3.2 in,
four rows of one), a taller figure keeping each panel's aspect, constrained layout instead of
the fixed margins (so titles, labels and the legend under the panels get their room), and every
title, legend title and legend entry wrapped at word boundaries to the width it has. Figures at
least NARROW_WIDTH wide are drawn as before, pixel for pixel.

Widths and heights in inches; text measured in points (pixels at the figure's resolution * 72 / dpi).
"""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np
from matplotlib.cbook import is_math_text
from matplotlib.figure import Figure

#: below this figure width (in) the figure is laid out for a single journal column
NARROW_WIDTH = 5.0
#: the narrowest column of panels a narrow figure gets (in)
PANEL_WIDTH = 1.6
#: the most columns of panels a narrow figure shows (one below NARROW_COLUMNS * PANEL_WIDTH)
NARROW_COLUMNS = 2
#: figure width (in) the designs' panel sizes are tuned for, and the margins it leaves them (in)
DESIGN_WIDTH, DESIGN_MARGINS = 7.2, 0.7
#: a narrow figure's panels: this fraction of the design's panel height (a single column is
#: also a page's height at most), plus room (in) per row for wrapped titles and tick labels
ROW_SCALE, ROW_ROOM = 0.75, 0.25
#: the lowest panel of a narrow figure (in): room for its tick labels and axis label
MIN_ROW = 1.1


def is_narrow(width: float) -> bool:
    """True when a figure `width` (in) wide is laid out as a narrow one."""
    return width < NARROW_WIDTH


def columns(cols: int, width: float) -> int:
    """The columns of panels a figure `width` (in) wide shows of `cols` logical ones: all of them at
    NARROW_WIDTH and wider; narrower, as many as fit PANEL_WIDTH wide, at most NARROW_COLUMNS and
    at least one (two from 3.2 in, one below)."""
    if not is_narrow(width):
        return cols
    return max(1, min(cols, NARROW_COLUMNS, int(width // PANEL_WIDTH)))


def height(w: float, h: float, rows: int, cols: int, width: float, margins: float) -> float:
    """The design height (in, of a design `w` wide) of a narrow figure `width` wide showing the
    rows x cols panels of the design w x h (margins: its top and bottom, in real inches) in
    columns(cols) columns, each ROW_SCALE as high for its width as in the design, plus ROW_ROOM."""
    pcols = columns(cols, width)
    prows = math.ceil(rows * cols / pcols)
    row = (h * DESIGN_WIDTH / w - margins) / rows  # one row's height at the design width (in)
    aspect = ((width - DESIGN_MARGINS) / pcols) / ((DESIGN_WIDTH - DESIGN_MARGINS) / cols)
    real = margins + prows * (max(ROW_SCALE * row * aspect, MIN_ROW) + ROW_ROOM)
    return real * w / width


def grid_axes(fig: Figure, rows: int, cols: int, *, sharex: bool, subplot_kw: dict, width: float) -> np.ndarray:
    """(rows, cols) array of axes in logical order: ``fig.subplots(rows, cols)`` at full width;
    narrow, the same axes laid out row by row in columns(cols) columns (panels left over after
    the last are removed)."""
    pcols = columns(cols, width)
    if pcols == cols:
        return np.atleast_2d(fig.subplots(rows, cols, sharex=sharex, squeeze=False, subplot_kw=subplot_kw))
    prows = math.ceil(rows * cols / pcols)
    flat = fig.subplots(prows, pcols, sharex=sharex, squeeze=False, subplot_kw=subplot_kw).ravel()
    for ax in flat[rows * cols :]:
        fig.delaxes(ax)
    return flat[: rows * cols].reshape(rows, cols)


#: a bare number (a value: ``0.4826``, ``-3``, ``1e+06``, ``?`` for one not stored), which keeps
#: the word after it (its unit) on its line
_VALUE = re.compile(r"[-+\u2212]?(?:\d+(?:[.,]\d+)*(?:[eE][-+]?\d+)?|\?)")
#: relations that keep the words either side on one line: ``\u03c9 = 1000 rpm``
_RELATIONS = frozenset("=\u2248\u00b1<>\u2264\u2265")
#: references that keep their number on their line: ``Fig. 4``, ``Table 1``
_REFERENCES = frozenset(("Fig.", "Figs.", "Table", "Eq."))


def _joins(before: str, word: str) -> bool:
    """Whether `word` stays on the line of the word `before` it: a relation and its neighbours,
    a value and its unit, a reference and its number, a name of one letter and its value (``A 2.38``)."""
    if word in _RELATIONS or before in _RELATIONS or before in _REFERENCES or _VALUE.fullmatch(before):
        return True
    return len(before) == 1 and before.isalpha() and _VALUE.match(word) is not None


#: arithmetic that makes a parenthesised group a formula: ``(K_xy \u2212 K_yx)``, ``(\u03c9 (C_xx + C_yy))``
_OPERATORS = frozenset("+\u2212/\u00d7\u00b7")


def _in_formulas(words: list[str]) -> set[int]:
    """Indices of the `words` that continue a parenthesised formula opened before them (a closed
    group, its parentheses nested, holding an arithmetic operator: :data:`_OPERATORS`)."""
    inside: set[int] = set()
    depth, start = 0, 0
    for i, word in enumerate(words):
        if depth == 0:
            start = i
        depth = max(0, depth + word.count("(") - word.count(")"))
        if depth == 0 and i > start and any(w == "-" or _OPERATORS & set(w) for w in words[start : i + 1]):
            inside.update(range(start + 1, i + 1))
    return inside


def _unbreakable(line: str) -> list[str]:
    """The words of `line` a wrapped line keeps together (:func:`_joins`; a parenthesised formula,
    :func:`_in_formulas`), each a piece joined by its spaces, so that no line ends in ``=`` or a
    value whose unit starts the next, nor inside ``(\u03c9 (C_xx + C_yy))``."""
    pieces: list[str] = []
    words = line.split(" ")
    formula = _in_formulas(words)
    for i, word in enumerate(words):
        if pieces and (i in formula or _joins(pieces[-1].rsplit(" ", 1)[-1], word)):
            pieces[-1] += " " + word
        else:
            pieces.append(word)
    return pieces


def wrap(fig: Figure, text: str, prop, width: float) -> str:
    """`text` with each line broken at spaces so that no line is wider than `width` (points)
    in font `prop` (a single word wider than that stays whole; mathtext, measured as drawn, holds
    no space); never inside a value with its unit, a condition's ``symbol = value unit`` or a
    parenthesised formula (:func:`_unbreakable`)."""
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]  # the Agg canvas of every report figure

    def wide(s: str) -> float:
        return renderer.get_text_width_height_descent(s, prop, ismath=is_math_text(s))[0] * 72.0 / renderer.dpi

    out = []
    for line in text.split("\n"):
        current = ""
        for word in _unbreakable(line):
            trial = f"{current} {word}" if current else word
            if current and wide(trial) > width:
                out.append(current)
                current = word
            else:
                current = trial
        out.append(current)
    return "\n".join(out)


def fit_texts(fig: Figure) -> None:
    """Wrap the suptitle to the figure's width, each axes title, x label and axes legend's title
    to its axes' width and its y label to its height (as placed before the constrained solver);
    drop the x label of a panel that shows no tick labels (a shared axis with panels below)."""
    fig_pt = fig.get_figwidth() * 72.0
    if fig.get_suptitle():
        _wrap_artist(fig, fig._suptitle, 0.96 * fig_pt)  # type: ignore[attr-defined]
    for ax in (a for a in fig.axes if a.get_visible()):
        box = ax.get_position()
        if not ax.xaxis.get_tick_params()["labelbottom"]:  # a logical last row with panels below it
            ax.set_xlabel("")  # the panels below carry the axis label with the values of its ticks
        _wrap_artist(fig, ax.yaxis.label, 1.1 * box.height * 72.0 * fig.get_figheight())
        titles = (ax.title, ax._left_title, ax._right_title)  # type: ignore[attr-defined]
        legend = ax.get_legend()
        for text in (*titles, ax.xaxis.label, *([legend.get_title()] if legend is not None else [])):
            _wrap_artist(fig, text, 0.95 * box.width * fig_pt)


def _wrap_artist(fig: Figure, text, width: float) -> None:
    """Wrap the Text artist `text` of `fig` to `width` (points)."""
    if text.get_text():
        text.set_text(wrap(fig, text.get_text(), text.get_fontproperties(), width))


def figure_legend(
    fig: Figure, handles: list, labels: list[str], *, ncols: int = 1, title: str | None = None, **kw: Any
):
    """A narrow figure's legend under its panels, outside them (constrained layout makes room, the
    figure grown by the legend's height: the panels keep theirs): title and entries wrapped to
    the figure's width, as many of `ncols` columns as fit it."""
    kw.pop("loc", None)
    fig_pt = fig.get_figwidth() * 72.0
    probe = fig.legend(handles, labels, loc="outside lower center", ncols=1, title=title, **kw)
    entry = probe.get_texts()[0].get_fontproperties() if probe.get_texts() else None
    title_prop = probe.get_title().get_fontproperties()
    probe.remove()
    if title:
        title = wrap(fig, title, title_prop, 0.94 * fig_pt)
    if entry is not None:
        labels = [wrap(fig, label, entry, 0.8 * fig_pt) for label in labels]
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
    for n in range(max(1, ncols), 0, -1):
        legend = fig.legend(handles, labels, loc="outside lower center", ncols=n, title=title, **kw)
        if n == 1 or legend.get_window_extent(renderer).width <= 0.98 * fig.bbox.width:
            break
        legend.remove()
    w, h = fig.get_size_inches()  # the legend's room added, not taken from the panels
    fig.set_size_inches(w, h + legend.get_window_extent(renderer).height / fig.dpi)
    return legend
