"""Every figure a report draws of a stored run, checked as drawn into its PNG: the texts a figure
draws, and :func:`checked_figures`, which draws the figures of some kinds at a width and gives
what a check found in each."""

from __future__ import annotations

from collections.abc import Callable
import re
from typing import TypeVar

import pytest
from matplotlib.cbook import is_math_text
from matplotlib.figure import Figure
from matplotlib.mathtext import MathTextParser
from matplotlib.text import Text

from orbitrig.analysis import plot_panels, plots
from orbitrig.analysis.report import FIGURES, Report, ReportOptions, draw_point, summary_plot_for
from orbitrig.analysis.report_analysis import analyse_point
from orbitrig.store.reader import read_run

KINDS = ("forces", "coefficients", "derived", "impedance", "coherence", "lms", "signals", "orbits", "summary")

T = TypeVar("T")


def figure_texts(fig) -> list[Text]:
    """Every text `fig` draws: suptitle, legends, and per visible axes its titles, texts, axis
    labels, offset texts and the tick labels of the ticks it draws."""
    out = list(fig.texts)  # the suptitle among them
    legends = [*fig.legends, *(ax.get_legend() for ax in fig.axes if ax.get_visible())]
    for legend in (lg for lg in legends if lg is not None and lg.get_visible()):
        out += [legend.get_title(), *legend.get_texts()]
    for ax in (a for a in fig.axes if a.get_visible()):
        out += [ax.title, ax._left_title, ax._right_title, *ax.texts]
        for axis in (ax.xaxis, ax.yaxis):
            out += [axis.label, axis.get_offset_text()]
            for tick in axis._update_ticks():
                out += [tick.label1, tick.label2]
    return [t for t in dict.fromkeys(out) if t.get_visible() and t.get_text().strip() != ""]


def drawn_figures(run_dir, out, width: float, kinds: tuple[str, ...]) -> dict[str, list[Figure]]:
    """{kind: [each of its figures]} of the run in `run_dir` drawn `width` in wide: the figures of
    `kinds` (the summary when it is among them), each kept as drawn into its PNG (after its canvas
    drew it at the figure's own dpi). Nothing changes a figure once written, so checks of several
    modules may look at one drawing (tests/report/conftest.py: synthetic_figures)."""
    found: dict[str, list[Figure]] = {}
    pending: list[Figure] = []
    original_png, original_write = plots.png_bytes, plots.write_atomic

    def kept(fig, dpi, text=None):  # the figure as drawn into its PNG
        data = original_png(fig, dpi, text)
        fig.canvas.draw()  # at the figure's own dpi, so that extents and the figure's box agree
        pending.append(fig)
        _out_of_the_pool(fig)
        return data

    def write(path, data):  # the PNG's name gives its kind
        if path.suffix == ".png":
            found.setdefault(path.name.split("_")[0].removesuffix(".png"), []).append(pending.pop())
        return original_write(path, data)

    run = read_run(run_dir)
    style = plots.FigureStyle(width=width)
    plots.use_style(style)
    mp = pytest.MonkeyPatch()
    try:
        mp.setattr(plots, "png_bytes", kept)
        mp.setattr(plots, "write_atomic", write)
        first, *others = run.complete_points
        options = ReportOptions(figures=frozenset(kinds) & frozenset(FIGURES), style=style)
        reports = [draw_point(run, first, out, options), *map(analyse_point, others)]
        if "summary" in kinds:
            summary_plot_for(Report(run, out, reports))
    finally:
        mp.undo()
        plots.use_style(plots.FigureStyle())
    return found


def _out_of_the_pool(fig: Figure) -> None:
    """`fig` no longer handed out again by this thread's pool of panel figures (plot_panels.panels
    reuses the figure of a shape for the next figure of that shape): kept as drawn, not redrawn by
    the next figure of its shape (the strain forces after the piezo ones, another test's drawing)."""
    pool = plot_panels._PANELS.__dict__.get("figures", {})
    for key in [key for key, held in pool.items() if held[0] is fig]:
        del pool[key]


def checked_figures(
    run_dir, out, width: float, kinds: tuple[str, ...], check: Callable[[Figure], T]
) -> dict[str, list[T]]:
    """{kind: [check(figure) of each of its figures]} of :func:`drawn_figures`."""
    return checks(drawn_figures(run_dir, out, width, kinds), kinds, check)


def checks(
    figures: dict[str, list[Figure]], kinds: tuple[str, ...], check: Callable[[Figure], T]
) -> dict[str, list[T]]:
    """{kind: [check(figure) of each of its figures]} of the `kinds` among `figures` (those drawn)."""
    return {kind: [check(fig) for fig in figs] for kind, figs in figures.items() if kind in kinds}


_MATHTEXT = MathTextParser("path")


def printed_pt(text) -> float:
    """The size (pt) `text` prints its smallest glyph at: mathtext lays out each glyph at its own
    size (a subscript's or superscript's smaller than the text's), plain text at the text's; a text
    of several lines line by line, as matplotlib lays it out."""
    lines = [line for line in text.get_text().split("\n") if is_math_text(line)]
    if not lines:
        return text.get_fontsize()
    laid_out = [_MATHTEXT.parse(line, dpi=72, prop=text.get_fontproperties()) for line in lines]
    return min(glyph[1] for layout in laid_out for glyph in layout.glyphs)


def shown(text: str) -> str:
    """What of `text` the page shows as written: mathtext's math parts dropped, but an escaped
    underscore or caret kept (drawn literally)."""
    if not is_math_text(text):
        return text
    parts = re.split(r"(?<!\\)\$", text)
    kept = [part if n % 2 == 0 else "".join(re.findall(r"\\[_^]", part)) for n, part in enumerate(parts)]
    return "".join(kept)


#: what a page shows of a name or formula written in ASCII: an underscore or caret (a subscript or
#: power not drawn as one), Greek letters spelled out, a hyphen between spaces standing for the
#: minus sign (−) and a constant term's index on the line (K0: the paper writes the constant K)
ASCII_STAND_INS = re.compile(r"[_^]|\s-\s|\b[KCDZ]0\b|\b(?:[Oo]mega|gamma|epsilon|eps|beta|Delta|chi)\d*\b")

#: a matrix entry named without its subscript (Kxx, Cyx_1, Zxy): the paper writes K_xx; a force on
#: the journal likewise (Fx: the paper writes F_x)
PLAIN_ENTRY = re.compile(r"\b(?:[KCDZ](?:xx|xy|yx|yy)|F[xy])\b")


def plain_entries(fig) -> list[str]:
    """Texts naming a matrix entry or a force unsubscripted (outside mathtext)."""
    return [f"unsubscripted: {t.get_text()!r}" for t in figure_texts(fig) if PLAIN_ENTRY.search(shown(t.get_text()))]


#: a unit a figure writes a value at (the conditions' and the display units), as a line's first word
UNIT_WORD = re.compile(r"(?:rpm|MPa|Pa|Hz|N|kN|MN/m|kg|\u00b5m|deg)[,;:)]?")
#: a bare number, as a line's last word
VALUE_WORD = re.compile(r"[-+\u2212]?\d+(?:[.,]\d+)*(?:[eE][-+]?\d+)?")


def split_values(text: str) -> list[str]:
    """The line breaks of `text` inside a value with its unit or a condition's ``symbol = value``:
    a line that ends in ``=``, one that starts with a unit, one ending in a bare number whose
    next line starts with a word (its unit), or a line ending in a name of one letter or a
    reference (``B``, ``Fig.``) whose value or number starts the next. A definition set on two lines, its second starting
    with ``=`` (the derived figure's ``C_eff,xx`` / ``= C_xx - K_xy/Omega``), is the display style.
    Also each parenthesised formula broken over lines (:func:`split_formulas`)."""
    lines = [line.strip() for line in text.split("\n")]
    out = []
    for a, b in zip(lines, lines[1:]):
        last, first = (a.split(" ") or [""])[-1], (b.split(" ") or [""])[0]
        named = (len(last) == 1 and last.isalpha() or last in ("Fig.", "Table")) and VALUE_WORD.match(first)
        if last == "=" or UNIT_WORD.fullmatch(first) or VALUE_WORD.fullmatch(last) and first or named:
            out.append(f"broken between {a!r} and {b!r}")
    return out + split_formulas(text)


def split_formulas(text: str) -> list[str]:
    """The parenthesised formulas of `text` (a group holding + \u2212 / \u00d7 \u00b7) broken over two lines: at a
    single column's width the whirl frequency ratio's title read ``(\u03c9 (C_xx`` / ``+ C_yy))``."""
    opened: list[int] = []
    out = []
    for i, c in enumerate(text):
        if c == "(":
            opened.append(i)
        elif c == ")" and opened:
            group = text[opened.pop() : i + 1]
            if "\n" in group and set(group) & set("+\u2212/\u00d7\u00b7"):
                out.append(f"formula broken: {group!r}")
    return out
