"""Every figure kind at a journal's single-column width (85 mm, 7.5 pt text) is readable: each
piece of text lies inside the figure, no title, axis label or tick label overlaps another text
and neighbouring tick labels stand apart (renderer extents, as drawn into the PNG). So are, at the
other narrow widths (4.9 in, just under the full layout's 5 in, and 3.0 in, one column of panels),
the kinds of more than two columns of panels; and a narrow figure shows at most two columns of
panels. Every kind is readable at the double column's width too, and a title wrapped to any width
keeps each value with its unit."""

from __future__ import annotations

import itertools
import re

import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.font_manager import FontProperties
from matplotlib.text import Text

from orbitrig.analysis import plots
from orbitrig.analysis import plots_narrow as narrow
from orbitrig.analysis.typeset import lifted_size
from support.report_figures import KINDS, checked_figures, checks, figure_texts, split_formulas, split_values

#: the kinds of more than two columns of panels (at full width)
MANY_COLUMNS = ("coefficients", "derived", "impedance", "orbits", "summary")


def _problems(fig) -> list[str]:
    """Texts outside the figure, and pairs of texts whose boxes overlap (inside one legend or
    one table cell grid, texts are placed by matplotlib side by side: not compared)."""
    renderer = fig.canvas.get_renderer()
    box = fig.bbox
    out = []
    boxes = []
    for t in figure_texts(fig):
        e = t.get_window_extent(renderer)
        if e.width == 0 or e.height == 0:
            continue
        if e.x0 < box.x0 - 0.5 or e.x1 > box.x1 + 0.5 or e.y0 < box.y0 - 0.5 or e.y1 > box.y1 + 0.5:
            out.append(f"outside the figure: {t.get_text()!r} {e.bounds} in {box.bounds}")
        boxes.append((t, e))
    grid: dict[int, set[int]] = {}  # per axes, the ids of its texts (looked up once, not per pair)
    for (a, ea), (b, eb) in itertools.combinations(boxes, 2):
        if _same_group(a, b, grid):
            continue
        if ea.overlaps(eb):
            w = min(ea.x1, eb.x1) - max(ea.x0, eb.x0)
            h = min(ea.y1, eb.y1) - max(ea.y0, eb.y0)
            if w > 1 and h > 1:  # more than a pixel both ways (at the figure's 300 dpi, 0.24 pt)
                out.append(f"overlap: {a.get_text()!r} and {b.get_text()!r}")
    return out + _crowded_ticks(fig)


#: the least room (pt) between neighbouring tick labels of one axis
TICK_GAP_PT = 1.0


def _crowded_ticks(fig) -> list[str]:
    """Neighbouring x tick labels of a panel less than TICK_GAP_PT apart (at 7 pt a single column's
    Ω/ω labels 0.25 0.50 0.75 touched, read as one number, without overlapping)."""
    renderer = fig.canvas.get_renderer()
    out = []
    for ax in (a for a in fig.axes if a.get_visible() and a.xaxis.get_visible()):
        left, right = ax.bbox.x0 - 0.5, ax.bbox.x1 + 0.5
        ticks = [t for t in ax.get_xticklabels() if t.get_visible() and t.get_text() and t.get_rotation() == 0]
        boxes = sorted(((t.get_window_extent(renderer), t.get_text()) for t in ticks), key=lambda box: box[0].x0)
        boxes = [(e, text) for e, text in boxes if left <= (e.x0 + e.x1) / 2 <= right]  # the ticks shown
        for (a, ta), (b, tb) in zip(boxes, boxes[1:]):
            if (b.x0 - a.x1) * 72.0 / fig.dpi < TICK_GAP_PT:
                out.append(f"tick labels {ta!r} and {tb!r} {(b.x0 - a.x1) * 72.0 / fig.dpi:.2f} pt apart")
    return out


def _same_group(a: Text, b: Text, grid: dict[int, set[int]]) -> bool:
    """Texts a figure places in a grid by design (cell values of the coherence table): both among
    the texts of one axes (``grid``: the ids of each axes' texts, filled as asked)."""
    if a.axes is None or a.axes is not b.axes:
        return False
    if id(a.axes) not in grid:
        grid[id(a.axes)] = {id(t) for t in a.axes.texts}
    return id(a) in grid[id(a.axes)] and id(b) in grid[id(a.axes)]


def _figure_problems(run_dir, out, width: float, kinds: tuple[str, ...]) -> dict[str, list[list[str]]]:
    """{kind: [problems of each of its figures]} of the run in `run_dir` drawn `width` in wide."""
    return checked_figures(run_dir, out, width, kinds, _problems)


def _report(found: dict[str, list[list[str]]], kinds: tuple[str, ...]) -> None:
    assert set(found) == set(kinds)
    problems = [f"{kind}: {p}" for kind, figs in found.items() for fig in figs for p in fig]
    assert not problems, "\n".join(problems[:20])


@pytest.fixture(scope="module")
def single_width_figures(synthetic_figures):
    """{kind: [problems of each of its figures]} of the synthetic run drawn at 85 mm."""
    return checks(synthetic_figures("single"), KINDS, _problems)


def test_every_figure_kind_is_readable_at_single_width(single_width_figures):
    _report(single_width_figures, KINDS)


def test_every_figure_kind_is_readable_at_double_width(synthetic_figures):
    """The same at the double column's width (175 mm), where titles are not wrapped: the orbit
    panels' titles side by side, five columns of them, do not run into each other."""
    _report(checks(synthetic_figures("double"), KINDS, _problems), KINDS)


@pytest.mark.parametrize("width", [4.9, 3.0])
def test_kinds_of_many_columns_are_readable_at_other_narrow_widths(width, synthetic_run, tmp_path):
    """The kinds whose panels go in fewer columns than they have (forces, lms and signals have
    two, coherence one: laid out at 4.9 in as at 3.5 in), at 4.9 and 3.0 in."""
    _report(_figure_problems(synthetic_run, tmp_path, width, MANY_COLUMNS), MANY_COLUMNS)


@pytest.mark.parametrize("width", [3.2, 3.5, 4.8, 4.9, 4.99])
def test_a_narrow_figure_has_at_most_two_columns(width):
    assert narrow.columns(4, width) == narrow.columns(5, width) == 2
    assert narrow.columns(2, width) == 2 and narrow.columns(1, width) == 1


@pytest.mark.parametrize("width", [1.0, 2.5, 3.0, 3.19])
def test_one_column_below_two_panel_widths(width):
    assert narrow.columns(4, width) == narrow.columns(2, width) == 1


def test_full_width_keeps_every_column():
    assert narrow.columns(5, narrow.NARROW_WIDTH) == 5 and narrow.columns(4, 7.2) == 4


#: a figure's title as the report writes it: the kind, then the point's conditions
TITLE = (
    "Rotordynamic coefficients, model kcd11, piezo load cells\npoint 0000: \u03c9 = 1000 rpm, "
    "\u03b5$_\\mathrm{d}$ = 0.04, \u03b5$_\\mathrm{s}$ = 0, p$_\\mathrm{r}$ = 0.4826 MPa, \u03b2 = 0.25"
)


def test_a_title_is_never_wrapped_inside_a_value_and_its_unit():
    """Wrapped to any width, a title keeps each condition's ``symbol = value unit`` on one line
    (at a single column's width the title's second line was broken as ``p_r =`` / ``0.4826 MPa``)."""
    fig = Figure(figsize=(3.5, 4.0))
    FigureCanvasAgg(fig)
    style = plots.FigureStyle(width=3.5)
    prop = FontProperties(size=lifted_size(TITLE, 1.2 * style.font, style.small))  # the suptitle's, as printed
    single = narrow.wrap(fig, TITLE, prop, 0.96 * 3.5 * 72.0).split("\n")  # its width (fit_texts)
    assert len(single) == 4 and single[-1].startswith("p$_\\mathrm{r}$ = 0.4826 MPa")  # 9 pt, its subscripts 8.4
    for width in range(60, 420, 6):
        wrapped = narrow.wrap(fig, TITLE, prop, float(width))
        assert wrapped.replace("\n", " ") == TITLE.replace("\n", " ")  # broken at spaces, nothing lost
        assert split_values(wrapped) == [], (width, wrapped)
    for broken in (
        "p$_\\mathrm{r}$ = 0.4826\nMPa",
        "\u03c9 =\n1000 rpm",
        "(paper Fig.\n4)",
        "radius A 2.38 \u00b5m, B\n2.40 \u00b5m",
    ):
        assert split_values(broken), broken  # the check sees each
        assert split_values(narrow.wrap(fig, broken.replace("\n", " "), prop, 1.0)) == []  # a line a piece, none split


def test_a_parenthesised_formula_is_never_wrapped_inside(synthetic_figures):
    """The whirl frequency ratio's title at a single column's panel keeps each parenthesised group of
    its formula whole, (K_xy \u2212 K_yx) / and (\u03c9 (C_xx + C_yy)) a line each (it read ``(\u03c9 (C_xx`` /
    ``+ C_yy))``); wrapped to any width, no group is broken and nothing is lost."""
    figures = synthetic_figures("single")["derived"]
    titles = [ax.get_title() for fig in figures for ax in fig.axes if ax.get_title().startswith("whirl")]
    assert len(titles) == len(figures) >= 1
    k, c = "K$_\\mathrm{%s}$", "C$_\\mathrm{%s}$"
    for title in titles:
        assert title.split("\n")[1:] == [f"({k % 'xy'} \u2212 {k % 'yx'}) /", f"(\u03c9 ({c % 'xx'} + {c % 'yy'}))"]
    fig = Figure(figsize=(3.35, 4.0))
    FigureCanvasAgg(fig)
    prop = FontProperties(size=7.5)
    for width in range(20, 300, 5):
        wrapped = narrow.wrap(fig, titles[0], prop, float(width))
        assert wrapped.replace("\n", " ") == titles[0].replace("\n", " ")
        assert split_formulas(wrapped) == [], (width, wrapped)
    assert (
        split_formulas("(\u03c9 (C\n+ C))")
        and split_formulas("(a \u2212\nb)")
        and not split_formulas("(paper\nFig. 4)")
    )


def test_the_forces_residual_titles_take_three_lines_at_most_at_single_width(synthetic_figures):
    """Wrapped to a single column's panel, each residual panel's title keeps its words on three lines
    (two at 6.5 pt; set 8.6 pt high for its subscript, it took four)."""
    figures = synthetic_figures("single")["forces"]
    titles = [ax.get_title() for fig in figures for ax in fig.axes if "residual" in ax.get_title()]
    assert len(titles) == 2 * len(figures) >= 4
    for title in titles:
        assert title.count("\n") <= 2, title
        assert title.replace("\n", " ").endswith(" residual: |measured \u2212 reproduced| phasor"), title


def test_the_signals_panel_titles_take_three_lines_at_most_at_single_width(synthetic_figures):
    """Wrapped to a single column's panel, each signals panel's title keeps to three lines (it took
    five: what the legend gives, both systems' averages of n revolutions, one revolution and the
    average, is left to it) and still states the differences and both RMS deviations with a unit."""
    figures = synthetic_figures("single")["signals"]
    titles = [ax.get_title() for fig in figures for ax in fig.axes if ax.get_visible()]
    assert len(titles) == 4 * len(figures) >= 4
    assert [t for t in titles if t.count("\n") > 2] == []
    flat = [t.replace("\n", " ") for t in titles]
    assert all(
        re.search(r"piezo \u2212 strain: (amplitude )?[+\u2212]\S+ % of \|piezo\|, phase [+\u2212]\S+ deg$", t)
        for t in flat[0::4] + flat[1::4]
    )
    assert all(re.search(r"fundamental: raw \S+, average \S+ N$", t) for t in flat[2::4] + flat[3::4])
    assert [t for t in flat if re.search(r"(?<![\w.])-\d", t)] == []  # a negative number's minus sign, U+2212
    legend = [t.get_text() for fig in figures for t in fig.legends[0].get_texts()]
    assert {"piezo, average of 8", "strain, average of 8", "piezo, revolution 1 (raw)"} <= set(legend)


#: the least room (pt) between an orbit panel's title and the title beside it or the panel above it
TITLE_GAP_PT = 5.0


def _title_gaps(fig) -> tuple[list[float], list[float]]:
    """(pt from each panel's title to the next title on its right, pt from each panel's title up to
    the panel above it: its tick labels and axis labels) of the visible panels of `fig`."""
    renderer = fig.canvas.get_renderer()
    axes = [ax for ax in fig.axes if ax.get_visible()]
    titles = {id(ax): ax.title.get_window_extent(renderer) for ax in axes}
    panels = {id(ax): ax.get_tightbbox(renderer) for ax in axes}
    beside, above = [], []
    for a, b in itertools.permutations(axes, 2):
        ta, tb, pb = titles[id(a)], titles[id(b)], panels[id(b)]
        if abs(ta.y0 - tb.y0) < 1 and tb.x0 > ta.x0:
            beside.append(tb.x0 - ta.x1)
        if pb.y0 > ta.y0 and min(ta.x1, pb.x1) > max(ta.x0, pb.x0):
            above.append(pb.y0 - ta.y1)
    return [g * 72.0 / fig.dpi for g in beside], [g * 72.0 / fig.dpi for g in above]


@pytest.mark.parametrize("width", sorted(plots.COLUMN_WIDTHS))
def test_the_orbit_panels_titles_stand_apart(synthetic_figures, width):
    """Each orbit panel's title (its frequency, its planes' mean radii) stands TITLE_GAP_PT at least
    from the title beside it and from the panel above it: at the double column's width, five panels
    a row, neighbouring titles were 2.1 pt apart and 1.7 pt under the tick labels above."""
    for fig in synthetic_figures(width)["orbits"]:
        beside, above = _title_gaps(fig)
        assert width == "single" or len(beside) == 4 * 10  # double: four rows of five, ten pairs a row
        assert len(above) >= 15 and min(above) >= TITLE_GAP_PT, (width, min(above))
        assert min(beside, default=TITLE_GAP_PT) >= TITLE_GAP_PT, (width, min(beside))
        titled = re.compile(r"[\d.]+ Hz (?:forward|backward) mean radius A [\d.]+, B [\d.]+ \u00b5m")
        assert all(titled.fullmatch(ax.get_title().replace("\n", " ")) for ax in fig.axes if ax.get_visible())
