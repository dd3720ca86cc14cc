"""Every figure kind at a journal's single-column width (3.5 in, 6.5 pt text) is readable: each
piece of text lies inside the figure, no title, axis label or tick label overlaps another text
(renderer extents, as drawn into the PNG)."""

from __future__ import annotations

import itertools

import pytest
from matplotlib.text import Text

from orbitrig.analysis import plots
from orbitrig.analysis.report import Report, ReportOptions, analyse_point, draw_point, summary_plot_for
from orbitrig.store.reader import read_run

KINDS = ("forces", "coefficients", "derived", "impedance", "coherence", "lms", "signals", "orbits", "summary")


def _texts(fig) -> list[Text]:
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


def _problems(fig) -> list[str]:
    """Texts outside the figure, and pairs of texts whose boxes overlap (inside one legend or
    one table cell grid, texts are placed by matplotlib side by side: not compared)."""
    fig.canvas.draw()  # at the figure's own dpi, so that extents and the figure's box agree
    renderer = fig.canvas.get_renderer()
    box = fig.bbox
    out = []
    boxes = []
    for t in _texts(fig):
        e = t.get_window_extent(renderer)
        if e.width == 0 or e.height == 0:
            continue
        if e.x0 < box.x0 - 0.5 or e.x1 > box.x1 + 0.5 or e.y0 < box.y0 - 0.5 or e.y1 > box.y1 + 0.5:
            out.append(f"outside the figure: {t.get_text()!r} {e.bounds} in {box.bounds}")
        boxes.append((t, e))
    for (a, ea), (b, eb) in itertools.combinations(boxes, 2):
        if _same_group(a, b):
            continue
        if ea.overlaps(eb):
            w = min(ea.x1, eb.x1) - max(ea.x0, eb.x0)
            h = min(ea.y1, eb.y1) - max(ea.y0, eb.y0)
            if w > 1 and h > 1:  # more than a pixel at 72 dpi both ways
                out.append(f"overlap: {a.get_text()!r} and {b.get_text()!r}")
    return out


def _same_group(a: Text, b: Text) -> bool:
    """Texts a figure places in a grid by design (cell values of the coherence table)."""
    return a.axes is not None and a.axes is b.axes and a in a.axes.texts and b in b.axes.texts


@pytest.fixture(scope="module")
def single_width_figures(synthetic_run, tmp_path_factory):
    """{kind: [problems of each of its figures]} of the synthetic run drawn at 3.5 in."""
    out = tmp_path_factory.mktemp("single")
    found: dict[str, list[list[str]]] = {}
    pending: list[list[str]] = []
    original_png, original_write = plots.png_bytes, plots.write_atomic

    def checked(fig, dpi):  # the figure as drawn into its PNG
        data = original_png(fig, dpi)
        pending.append(_problems(fig))
        return data

    def write(path, data):  # the PNG's name gives its kind
        if path.suffix == ".png":
            found.setdefault(path.name.split("_")[0].removesuffix(".png"), []).append(pending.pop())
        return original_write(path, data)

    run = read_run(synthetic_run)
    style = plots.FigureStyle(width=plots.COLUMN_WIDTHS["single"])
    plots.use_style(style)
    mp = pytest.MonkeyPatch()
    try:
        mp.setattr(plots, "png_bytes", checked)
        mp.setattr(plots, "write_atomic", write)
        first, *others = run.complete_points
        reports = [draw_point(run, first, out, ReportOptions(style=style)), *map(analyse_point, others)]
        summary_plot_for(Report(run, out, reports))
    finally:
        mp.undo()
        plots.use_style(plots.FigureStyle())
    return found


def test_every_figure_kind_is_readable_at_single_width(single_width_figures):
    assert set(single_width_figures) == set(KINDS)
    problems = [f"{kind}: {p}" for kind, figs in single_width_figures.items() for fig in figs for p in fig]
    assert not problems, "\n".join(problems[:20])
