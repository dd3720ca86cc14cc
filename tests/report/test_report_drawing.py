"""The report's drawing shortcuts draw what matplotlib draws: axes that measure tick labels once
per draw and per tight box, skip the autoscale question and clip to a frame transform made once
(analysis/report_axes.py), text
measured once per process, mathtext drawn once per process and the PNG written with ISA-L's deflate
(analysis/canvas.py)."""

from __future__ import annotations

import io
import zlib

import numpy as np
import pytest
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from PIL import Image

from matplotlib.backends.backend_agg import RendererAgg
from matplotlib.font_manager import FontProperties

from orbitrig.analysis import canvas
from orbitrig.analysis.canvas import LAYOUT_CACHE_SIZE, CachedTextRenderer, png_bytes
from orbitrig.analysis.report_axes import ReportAxes


def _figure(axes_class, scale: float, *, align: bool = False) -> Figure:
    """Six panels sharing x, tick labels of widths that differ by panel and by `scale`, axis
    labels, titles and a legend: what the label placement and the autoscaling have to get right."""
    fig = Figure(figsize=(7.2, 4.5), dpi=100)
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 3, sharex=True, subplot_kw={"axes_class": axes_class})
    x = np.linspace(0.1, 2.0, 40)
    for k, ax in enumerate(axes.flat):
        ax.plot(x, scale * 10.0 ** (k - 2) * np.sin(3 * x + k), "o-", label=f"panel {k}")
        ax.set_ylabel(f"y{k}  [unit]")
        ax.set_title(f"panel {k}")
    axes[0, 0].plot(x * 1.5, x, "--")  # widens the shared x range after the others were drawn in
    for ax in axes[-1]:
        ax.set_xlabel("Omega/omega  [-]")
    axes[0, 0].legend()
    if align:
        fig.align_labels()
    return fig


def _pixels(fig: Figure) -> np.ndarray:
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba()).copy()


@pytest.mark.parametrize("align", [False, True], ids=["own-labels", "aligned-labels"])
@pytest.mark.parametrize("scale", [1.0, -3.7e4])
def test_report_axes_draw_the_same_pixels_as_matplotlib(scale, align):
    expected = _pixels(_figure(Axes, scale, align=align))
    assert (_pixels(_figure(ReportAxes, scale, align=align)) == expected).all()


@pytest.mark.parametrize("ticks", ["both-sides-in", "one-restyled", "grid"])
def test_report_axes_tick_marks_drawn_together_are_matplotlibs_pixels(ticks, monkeypatch):
    """The tick marks of an axis drawn as one line of markers (ReportAxes on Agg) are the pixels of
    matplotlib's one line per tick: marks on all four sides pointing in, one tick restyled (drawn on
    its own), grid lines shown (every tick drawn as matplotlib draws it)."""
    drawn, calls = [], []
    draw = Line2D.draw  # a tick mark is a Line2D of one marker

    def counted(line, renderer):
        calls.extend([cls] if line.get_visible() else [])
        draw(line, renderer)

    monkeypatch.setattr(Line2D, "draw", counted)
    for cls in (Axes, ReportAxes):
        fig = _figure(cls, -3.7e4)
        for ax in fig.axes:
            if ticks == "both-sides-in":
                ax.tick_params(direction="in", top=True, right=True, length=5, width=1.3)
            elif ticks == "one-restyled":
                ax.xaxis.get_major_ticks()[1].tick1line.set_markeredgecolor("red")
            else:
                ax.grid(True, alpha=0.4)
        drawn.append(_pixels(fig))
    assert (drawn[1] == drawn[0]).all()
    if ticks == "both-sides-in":  # each side's tick marks drawn at once, not one line per tick
        assert calls.count(ReportAxes) < 0.5 * calls.count(Axes)
    elif ticks == "one-restyled":  # the y axes' at once, the x axes' one by one
        assert calls.count(ReportAxes) < calls.count(Axes)


def test_light_grid_made_once_draws_after_the_limits_change_what_a_first_draw_draws():
    """light_grid's one collection of grid lines, made at the first draw and given each draw's lines,
    draws after new data moved the ticks what a grid drawn for the first time there draws, pixel
    for pixel (under matplotlib's default style, matplotlib's ``ax.grid`` too)."""
    import matplotlib

    from orbitrig.analysis.grid import light_grid

    def drawn(grid, data_first: bool) -> np.ndarray:
        fig = _figure(ReportAxes, 1.0)
        for ax in fig.axes:
            grid(ax)
        if not data_first:
            _pixels(fig)
        fig.axes[4].plot([-5.0, 9.0], [0.0, 20.0])  # every panel's x ticks and this one's y ticks move
        return _pixels(fig)

    again, first = drawn(light_grid, False), drawn(light_grid, True)
    assert (again == first).all()
    assert (again != drawn(lambda ax: None, True)).any()  # grid lines drawn
    with matplotlib.rc_context():
        matplotlib.rcdefaults()
        ours = drawn(light_grid, False)
        assert (ours == drawn(lambda ax: ax.grid(True, alpha=0.3), False)).all()


@pytest.mark.parametrize("cycle", [False, True], ids=["colour-cycle", "colour-and-style-cycle"])
def test_plot_line_makes_and_adds_the_line_ax_plot_makes(cycle):
    """plot_marks.plot_line draws the pixels and legend of ``ax.plot`` with the same arguments:
    formats ("-", ":", "--", "_", ".-", none), aliases, markers every so often, a colour from the
    property cycle (advanced as ax.plot advances it, also by a cycle of colours and line styles)."""
    from cycler import cycler

    from orbitrig.analysis.plot_marks import marks_along, plot_line

    calls = [
        (None, {"color": "C3", "lw": 2.0, "label": "fit", **marks_along(2)}),
        ("-", {"color": (0.2, 0.4, 0.6, 1.0), "label": "solid"}),
        (":", {"color": "k", "lw": 0.7}),
        ("--", {"label": "from the cycle"}),
        ("_", {"ms": 6.0, "mew": 1.3, "color": "red"}),
        (".-", {"color": "0.5", "ms": 3.5, "label": "raw"}),
        (None, {"ls": "none", "marker": "s", "mfc": "white", "label": "cycle again"}),
    ]
    drawn = []
    matplotlibs = lambda ax, x, y, fmt, kw: ax.plot(x, y, *([fmt] if fmt else []), **kw)  # noqa: E731
    ours = lambda ax, x, y, fmt, kw: plot_line(ax, x, y, fmt, **kw)  # noqa: E731
    for plot in (matplotlibs, ours):
        fig = _figure(ReportAxes, 1.0)
        ax = fig.axes[3]
        if cycle:
            ax.set_prop_cycle(cycler(color=["tab:orange", "tab:purple"], linestyle=["-.", "-"]))
        x = np.linspace(0.0, 2.5, 23)
        for k, (fmt, kw) in enumerate(calls):
            plot(ax, x, np.cos(x + k) * (k + 1), fmt, dict(kw))
        ax.legend(loc="lower left")
        drawn.append(_pixels(fig))
    assert (drawn[1] == drawn[0]).all()


def test_report_axes_clip_to_a_frame_transform_made_once_as_matplotlib_clips():
    """Lines, bands and bars reaching past the limits are clipped by ReportAxes (one frame transform
    for all, made again when the frame changes) to matplotlib's pixels, also for artists added
    after the frame was narrowed (they clip to the new frame, those before to the old, as there)."""
    drawn, shared = [], []
    for cls in (Axes, ReportAxes):
        fig = _figure(cls, 1.0)
        x = np.linspace(-1.0, 3.0, 30)
        for ax in fig.axes:
            ax.set_xlim(0.2, 1.8)
            ax.fill_between(x, np.sin(x) - 0.3, np.sin(x) + 0.3, alpha=0.3)
            ax.bar([0.1, 1.0, 1.9], [0.5, 2.0, 0.7], width=0.3, alpha=0.5)
        ax = fig.axes[1]
        ax.patch.set_width(0.6)  # the frame narrowed: what is added now is clipped to it
        ax.plot(x, 3 * np.cos(x), lw=3)
        drawn.append(_pixels(fig))
        shared.append({id(line.clipbox._transform) for line in fig.axes[0].lines + fig.axes[0].patches})
    assert (drawn[1] == drawn[0]).all()
    assert len(shared[0]) == 5 and len(shared[1]) == 1  # one transform per artist; one for all


@pytest.mark.parametrize("align", [False, True], ids=["own-labels", "aligned-labels"])
def test_report_axes_tight_boxes_are_matplotlibs(align):
    """Each panel's tight box (the legend's room is measured by them) and its labels' places, asked
    before any draw, as matplotlib's axes give them."""
    found = {}
    for cls in (Axes, ReportAxes):
        fig = _figure(cls, -3.7e4, align=align)
        renderer = fig.canvas.get_renderer()
        boxes = [tuple(ax.get_tightbbox(renderer).bounds) for ax in fig.axes]
        labels = [tuple(a.label.get_window_extent(renderer).bounds) for ax in fig.axes for a in (ax.xaxis, ax.yaxis)]
        found[cls] = boxes, labels
    assert found[ReportAxes] == found[Axes]


def test_text_extents_are_agg_s_and_kept_beyond_matplotlib_s_fifty_layouts():
    """The report's renderer measures plain text and mathtext as Agg does, and a mathtext string
    laid out before 60 others is not laid out again (matplotlib keeps 50)."""
    report, agg = CachedTextRenderer(400, 300, 300), RendererAgg(400, 300, 300)
    prop = FontProperties(size=6.5)
    for text, ismath in (("K  [MN/m]", False), ("0.25", False), ("K$_\\mathrm{xy,1}$  [MN/m]", True)):
        assert report.get_text_width_height_descent(text, prop, ismath) == agg.get_text_width_height_descent(
            text, prop, ismath
        )
    assert LAYOUT_CACHE_SIZE > 60
    first = report.mathtext_parser.parse("F$_\\mathrm{x}$", 300, prop)
    for n in range(60):
        report.mathtext_parser.parse(f"C$_\\mathrm{{{n}}}$", 300, prop)
    assert report.mathtext_parser.parse("F$_\\mathrm{x}$", 300, prop) is first


def _layout(laid) -> tuple:
    """A mathtext layout comparable across parsers: its box, glyphs (font file, size, glyph, place), rules."""
    return laid.width, laid.height, laid.depth, [(g[0].fname, *g[1:]) for g in laid.glyphs], laid.rects


def test_mathtext_segments_parsed_once_lay_out_as_matplotlib_s_parser():
    """A math segment met again in another string (a legend entry's numbers changed, the same
    subscripts) is not parsed again, and every string is laid out as matplotlib's own parser lays it
    out: after text, after another segment, after an operator's spacing, at other sizes and resolutions."""
    from matplotlib.ft2font import LoadFlags
    from matplotlib.mathtext import MathTextParser

    strings = [
        "kc7: C$_\\mathrm{eff,xx}$ = 0 at 11.72\xa0\u00b1\xa00.40\xa0Hz; C$_\\mathrm{eff,yy}$ = 0",
        "kc7: C$_\\mathrm{eff,xx}$ = 0 at 12.05\xa0\u00b1\xa00.41\xa0Hz; C$_\\mathrm{eff,yy}$ = 0",
        "$\\frac{a}{b}$ x$^{2}$ F$_\\mathrm{x}$",
        "a$x_1$ + $x_1$b",
        "$x_1$$+ y$",
        "$a_{b}=c$ $=d$",
        "$\\rm{A} x$ $x$",
    ]
    ours, theirs = canvas._LaidOut(), MathTextParser("path")
    for k in range(2):
        for s in strings[::-1] if k else strings:
            for size, dpi in ((6.0, 300), (6.5, 72)):
                prop = FontProperties(size=size)
                found = ours._parse_cached.__wrapped__(
                    ours, s, dpi, prop, True, LoadFlags.NO_HINTING
                )  # "path": unhinted
                laid = theirs._parse_cached.__wrapped__(
                    theirs, s, dpi, prop, True, LoadFlags.NO_HINTING
                )  # "path": unhinted
                assert _layout(found) == _layout(laid), (s, size, dpi)
    kept = len(ours._parser._parsed)
    ours.parse("kc7: C$_\\mathrm{eff,xx}$ = 0 at 9.99\xa0Hz", 300, FontProperties(size=6.0))
    assert len(ours._parser._parsed) == kept  # its segment parsed before


@pytest.mark.parametrize("angle", [0.0, 90.0, 30.0])
def test_mathtext_drawn_once_per_process_is_what_agg_draws_at_a_whole_pixel(angle):
    """A mathtext string (subscripts, superscripts, a fraction's bar) copied from the per-process
    cache lands where and as Agg draws it at a whole pixel, in any colour, twice (the second from
    the cache), partly beyond the canvas' edge too; off a whole pixel it moves by less than one."""
    prop = FontProperties(size=6.5)
    strings = ("K$_\\mathrm{xy,1}$  [MN/m]", "$\\frac{a}{b}$ x$^{2}$ F$_\\mathrm{x}$")
    drawn = []
    for renderer in (RendererAgg(500, 300, 300), CachedTextRenderer(500, 300, 300)):
        gc = renderer.new_gc()
        gc.set_foreground((0.1, 0.2, 0.7))
        for k, s in enumerate(strings):
            for x, y in ((40, 150 + 60 * k), (41, 152 + 60 * k), (420, 100)):
                renderer.draw_text(gc, x, y, s, prop, angle, ismath=True)
        gc.restore()
        drawn.append(np.asarray(renderer.buffer_rgba()).copy())
    assert (drawn[0][:, :, 3] > 0).sum() > 3000  # ink drawn
    assert (drawn[1] == drawn[0]).all()
    assert {s for s, *_ in canvas._MATH} >= set(strings)  # kept drawn
    off = [RendererAgg(300, 200, 300), CachedTextRenderer(300, 200, 300)]
    for renderer, (x, y) in zip(off, ((100, 100), (100.4, 100.3))):
        gc = renderer.new_gc()
        renderer.draw_text(gc, x, y, strings[0], prop, angle, ismath=True)
        gc.restore()
    ink = [np.argwhere(np.asarray(r.buffer_rgba())[:, :, 3] > 0) for r in off]
    assert (ink[0].min(axis=0) == ink[1].min(axis=0)).all() and (ink[0].max(axis=0) == ink[1].max(axis=0)).all()


@pytest.mark.parametrize("angle", [0.0, 30.0])
def test_mathtext_over_ink_and_clipped_is_what_agg_draws(angle):
    """Mathtext over a white face and a grid line (the figure's), and mathtext clipped to a box
    (an artist whose clip box is set), are what Agg draws, pixel for pixel: a clipped string copied
    as an image lost or kept 3 edge pixels otherwise than Agg's text does."""
    from matplotlib.path import Path
    from matplotlib.transforms import Affine2D, Bbox

    prop = FontProperties(size=6.5)
    drawn = []
    for renderer in (RendererAgg(400, 300, 300), CachedTextRenderer(400, 300, 300)):
        gc = renderer.new_gc()
        renderer.draw_path(
            gc, Path([(0, 0), (400, 0), (400, 300), (0, 300), (0, 0)], closed=True), Affine2D(), (1, 1, 1, 1)
        )
        gc.set_foreground((0.5, 0.5, 0.5))
        gc.set_linewidth(3)
        renderer.draw_path(gc, Path([(0, 140), (400, 160)]), Affine2D())
        gc.set_foreground((0.1, 0.2, 0.7))
        renderer.draw_text(gc, 40, 150, "K$_\\mathrm{xy,1}$  [MN/m]", prop, angle, ismath=True)
        gc.set_clip_rectangle(Bbox([[60, 30], [120, 120]]))
        renderer.draw_text(gc, 40, 250, "C$_\\mathrm{yx}$  [kN s/m]", prop, angle, ismath=True)
        gc.restore()
        drawn.append(np.asarray(renderer.buffer_rgba()).copy())
    assert (drawn[0][180:270, 60:120, 0] < 200).sum() > 20  # the clipped string's ink, inside its box
    assert (drawn[1] == drawn[0]).all()


def test_report_axes_autoscale_after_new_data_and_keep_shared_limits():
    """A line added after a draw widens every panel sharing x, as with matplotlib's axes."""
    figures = {cls: _figure(cls, 1.0) for cls in (Axes, ReportAxes)}
    limits = {}
    for cls, fig in figures.items():
        _pixels(fig)
        fig.axes[4].plot([-5.0, 9.0], [0.0, 1.0])
        _pixels(fig)
        limits[cls] = [ax.get_xlim() + ax.get_ylim() for ax in fig.axes]
    assert limits[ReportAxes] == limits[Axes]
    assert limits[ReportAxes][0][0] < -5.0 and limits[ReportAxes][0][1] > 9.0  # the shared x grew
    assert (_pixels(figures[ReportAxes]) == _pixels(figures[Axes])).all()


def test_report_axes_label_moves_with_wider_tick_labels():
    """The y label is placed clear of this draw's tick labels, not of an earlier draw's: where
    matplotlib's axes put it, left of the wider labels."""
    placed = {}
    for cls in (Axes, ReportAxes):
        fig = _figure(cls, 1.0)
        ax = fig.axes[2]  # tick labels -1.0 .. 1.0
        fig.canvas.draw()
        narrow = ax.yaxis.label.get_window_extent().x0
        ax.lines[0].set_ydata(ax.lines[0].get_ydata() * 1e5)  # tick labels -100000 .. 100000
        ax.relim()
        ax.autoscale_view()
        fig.canvas.draw()
        placed[cls] = narrow, ax.yaxis.label.get_window_extent().x0
    assert placed[ReportAxes] == placed[Axes]
    assert placed[ReportAxes][1] < placed[ReportAxes][0] - 5  # px: moved left


def test_png_is_the_canvas_in_a_standard_zlib_stream():
    fig = _figure(ReportAxes, 1.0)
    data = png_bytes(fig, 150)
    image = Image.open(io.BytesIO(data))
    assert image.mode == "RGB" and image.size == (1080, 675)
    assert image.info["dpi"] == pytest.approx((150, 150), abs=0.05)  # pHYs: whole pixels per metre
    fig.set_dpi(150)
    fig.canvas.draw()
    assert (np.asarray(image) == np.asarray(fig.canvas.buffer_rgba())[:, :, :3]).all()
    idat = data[data.index(b"IDAT") + 4 :]
    rows = zlib.decompressobj().decompress(idat)  # stops at the end of the stream
    assert len(rows) == 675 * (1 + 3 * 1080) and rows[0] == 0  # filter None on every row


def test_a_reused_figure_of_panels_gives_back_what_its_last_figure_set_on_them():
    """plot_panels.panels hands the next figure of a shape the axes of the last one, emptied: an
    orbit's equal aspect and no margins, a magnitude's ticks kept at zero and above (from_zero)
    must not reach a figure drawn next on them, whose data go below zero."""
    from matplotlib import rcParams
    from matplotlib.ticker import MaxNLocator

    from orbitrig.analysis.plot_marks import from_zero
    from orbitrig.analysis.plot_panels import panels

    fig, axes = panels(3.1, 2.7, 2, 2)
    ax = axes[0, 0]
    ax.plot([0.0, 1.0], [0.0, 2.0])
    ax.set_aspect("equal", adjustable="datalim")
    ax.margins(0)
    axes[1, 1].plot([0.0, 1.0], [0.0, 3.0])
    from_zero(axes[1, 1])
    again, axes = panels(3.1, 2.7, 2, 2)
    assert again is fig  # the same figure, reused
    for ax in axes.flat:
        assert ax.get_aspect() == "auto" and ax.margins() == (rcParams["axes.xmargin"], rcParams["axes.ymargin"])
        assert type(ax.yaxis.get_major_locator()) is MaxNLocator
    axes[1, 1].plot([0.0, 1.0], [-3.0, 3.0])
    again.canvas.draw()
    assert min(axes[1, 1].get_yticks()) < 0  # negative ticks shown again
