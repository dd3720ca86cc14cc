"""Report figures of many panels: fixed margins in inches for the style's text size (constrained
layout only for a narrow figure, plots_narrow), the figure of a shape reused per thread, at most
MAX_TICKS ticks per axis, and the legend under the panels with the figure grown until it clears
them by LEGEND_GAP (pt).
"""

from __future__ import annotations

import threading
from contextlib import nullcontext
from typing import Any

from matplotlib import rcParams
from matplotlib.cbook import is_math_text
from matplotlib.figure import Figure
from matplotlib.offsetbox import AnnotationBbox, OffsetBox
from matplotlib.ticker import MaxNLocator

from orbitrig.analysis import plots_narrow as narrow
from orbitrig.analysis.report_axes import ReportAxes
from orbitrig.analysis.plots import report_figure, style
from orbitrig.analysis.typeset import lift_scripts, lifted_size

#: ticks of each panel axis: at most MAX_TICKS intervals, at 1, 2, 2.5 or 5 times a power of 10 (TICK_STEPS)
MAX_TICKS = 5
TICK_STEPS = (1, 2, 2.5, 5, 10)
#: a narrow figure's steps: no quarter steps, whose labels take a digit more
NARROW_STEPS = (1, 2, 5, 10)
#: keyword arguments of every report figure's ``subplots``: axes that measure tick labels once per draw
AXES = {"axes_class": ReportAxes}
#: the room (pt) a figure's legend keeps below the lowest tick labels and axis labels of its panels
LEGEND_GAP = 4.0


def text_scale() -> float:
    """Margins drawn for 10-pt text, scaled to the style's text size."""
    return style().font / 10.0


def panel_figure(
    w: float,
    h: float,
    *,
    left: float = 0.85,
    right: float = 0.2,
    top: float = 0.95,
    bottom: float = 1.15,
    wspace: float = 0.42,
    hspace: float = 0.42,
) -> Figure:
    """A figure of many panels with fixed margins in inches (room for a two-line title on top and
    a legend at the bottom): half the saving time of constrained layout, whose solver measures
    every tick label. Put the legend with :func:`figure_legend`. A narrow figure
    (plots_narrow) is laid out by constrained layout instead."""
    if narrow.is_narrow(style().width):
        return report_figure(w, h)
    fig = report_figure(w, h, layout=None)
    t = text_scale() * w / style().width  # margins in design inches, for the style's text
    fig.subplots_adjust(
        left=left * t / w,
        right=1 - right * t / w,
        top=1 - top * t / h,
        bottom=bottom * t / h,
        wspace=wspace,
        hspace=hspace,
    )
    return fig


_PANELS = threading.local()  # this thread's figures of panels, by shape (reused: see panels)


def panels(w: float, h: float, rows: int, cols: int, *, sharex: bool = True, **margins: float) -> tuple[Figure, Any]:
    """(figure, 2-d array of axes) of :func:`panel_figure` with rows x cols panels: the figure
    this thread drew last of the same shape and style, emptied, or a new one. Reusing the axes
    (their axis objects, tick marks and labels) halves the cost of drawing a figure; the caller
    sets every title and label again. Valid until the next call of the same shape."""
    key = (w, h, rows, cols, sharex, tuple(sorted(margins.items())), style())
    cache = _PANELS.__dict__.setdefault("figures", {})
    if key in cache:
        fig, axes, size, margins_now = cache[key]
        _empty(fig)
        if tuple(fig.get_size_inches()) != size:  # grown for its legend (_room_below, narrow.figure_legend)
            fig.set_size_inches(*size)
            if fig.get_layout_engine() is None:  # fixed margins; a narrow figure's layout finds its own
                fig.subplots_adjust(bottom=margins_now[0], top=margins_now[1])
        return fig, axes
    if narrow.is_narrow(style().width):  # fewer columns of panels, a taller figure
        t = text_scale() * (margins.get("top", 0.95) + margins.get("bottom", 1.15))
        h = narrow.height(w, h, rows, cols, style().width, t)
    fig = panel_figure(w, h, **margins)
    axes = narrow.grid_axes(fig, rows, cols, sharex=sharex, subplot_kw=AXES, width=style().width)
    for ax in axes.flat:
        _panel_ticks(ax)
    cache[key] = fig, axes, tuple(fig.get_size_inches()), (fig.subplotpars.bottom, fig.subplotpars.top)
    return fig, axes


def max_columns(cols: int) -> int:
    """How many of `cols` columns of panels a figure of the style's width shows side by side."""
    return narrow.columns(cols, style().width)


def figure_legend(fig: Figure, handles: list, labels: list, *, fit: bool = False, **kw: Any):
    """The legend under a figure's panels: ``fig.legend(handles, labels, loc="lower center",
    fontsize=style().small, ...)`` in the margin the figure leaves it; in a narrow figure wrapped
    to its width, outside the panels (plots_narrow.figure_legend). The entries are set at the size
    their subscripts need to print at the smallest text size (typeset.lift_scripts), and so are the
    panels' texts before the legend's room is measured (the lifting when saved changes nothing); a
    legend wider than the figure has its entries wrapped to the figure's width. `fit`: the figure's
    height fitted to its legend, shrunk as well as grown (:func:`_room_below`), so that no empty band
    stays between the panels and a legend shorter than the margin left for it."""
    size = float(kw.pop("fontsize", style().small))
    kw["fontsize"] = max((lifted_size(str(label), size, style().small) for label in labels), default=size)
    if kw.get("title") and is_math_text(kw["title"]):  # a title with subscripts: measured (wrapped) at its size
        kw["title_fontsize"] = lifted_size(kw["title"], float(kw.get("title_fontsize", size)), style().small)
    lift_scripts(fig, style().small)
    if narrow.is_narrow(style().width):
        return narrow.figure_legend(fig, handles, labels, **kw)
    legend = fig.legend(handles, labels, **{"loc": "lower center", **kw})
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]  # the Agg canvas of every report figure
    extent = legend.get_window_extent(renderer)
    if extent.width > 0.98 * fig.bbox.width:  # title, entries wrapped to the figure's width
        entry = legend.get_texts()[0].get_fontproperties()
        room = 0.85 * fig.get_figwidth() * 72.0 / max(1, int(kw.get("ncols", 1)))
        if kw.get("title"):
            kw["title"] = narrow.wrap(
                fig, kw["title"], legend.get_title().get_fontproperties(), 0.94 * fig.get_figwidth() * 72.0
            )
        legend.remove()
        wrapped = [narrow.wrap(fig, str(label), entry, room) for label in labels]
        legend = fig.legend(handles, wrapped, **{"loc": "lower center", **kw})
        extent = legend.get_window_extent(renderer)
    _room_below(fig, extent, shrink=fit)
    return legend


def clear_y_labels(fig: Figure, axes) -> None:
    """Widen the gaps between the columns of `axes` (2-d, a fixed-margin :func:`panel_figure`) until
    each panel's y tick labels and y label clear its left neighbour's frame by LEGEND_GAP (pt):
    wide negative tick labels (−12.5) pushed a label over the panel beside it. A narrow
    figure's constrained layout keeps its own room; a figure whose labels clear stays as it was."""
    rows, cols = axes.shape
    if cols < 2 or fig.get_layout_engine() is not None:
        return
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]  # the Agg canvas of every report figure
    overlap = 0.0  # px
    for r in range(rows):
        for c in range(1, cols):
            ax, beside = axes[r, c], axes[r, c - 1]
            if not (ax.get_visible() and beside.get_visible()):
                continue
            box = ax.yaxis.get_tightbbox(renderer)
            if box is not None:
                overlap = max(overlap, beside.get_window_extent(renderer).x1 + LEGEND_GAP * fig.dpi / 72.0 - box.x0)
    if overlap <= 0:
        return
    p = fig.subplotpars
    room = (p.right - p.left) * fig.bbox.width  # px of the panels and their gaps
    gap = p.wspace * room / (cols + (cols - 1) * p.wspace) + overlap
    fig.subplots_adjust(wspace=gap / ((room - (cols - 1) * gap) / cols))


def _room_below(fig: Figure, extent, *, shrink: bool = False) -> None:
    """Grow `fig` at the bottom until its legend (on its lower edge, `extent`: its box in pixels)
    clears every panel, tick label and axis label by LEGEND_GAP (pt), or with `shrink` make it clear
    them by just that: the panels keep their size and their place from the top, however many
    entries the legend has. (:func:`panels` gives a reused figure its size back.)"""
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]  # the Agg canvas of every report figure
    bottoms = [_bottom(ax, renderer) for ax in _lowest_panels(fig)]
    lowest = min((b for b in bottoms if b is not None), default=None)
    if lowest is None:
        return
    overlap = extent.y1 + LEGEND_GAP * fig.dpi / 72.0 - lowest  # pixels
    if overlap <= 0 and not shrink:
        return
    w, h = fig.get_size_inches()
    grow = overlap / fig.dpi  # in
    bottom, top = fig.subplotpars.bottom, fig.subplotpars.top
    fig.set_size_inches(w, h + grow)
    fig.subplots_adjust(bottom=(bottom * h + grow) / (h + grow), top=(top * h + grow) / (h + grow))


def _bottom(ax, renderer) -> float | None:
    """The lower edge (px) of panel `ax`'s tight box (``ax.get_tightbbox``), None for none. When its
    x tick labels reach further below the frame than a font size of its y tick labels (unrotated
    labels centred on ticks inside the frame reach half a line below it at most), its y tick labels
    and titles (above the frame) cannot be the lowest: the frame, the x axis, the bottom spine (tick
    marks), the y axis' label and the panel's texts and legend are measured; every artist of another
    kind must then be clipped to the frame (an offset box is not). Otherwise, or with inset axes,
    a table or a locator, matplotlib's tight box."""
    shown = (*ax.lines, *ax.collections, *ax.patches, *ax.images, *ax.artists)  # the artists: light_grid's
    y_ticks = [t.label1 for t in (*ax.yaxis.majorTicks[:1], *ax.yaxis.minorTicks[:1])]
    if (
        not ax.get_visible()
        or not (ax.axison and ax.xaxis.get_visible())
        or ax.get_axes_locator() is not None
        or ax.child_axes
        or ax.tables
        or any(a.get_visible() and (not a.get_clip_on() or isinstance(a, (OffsetBox, AnnotationBbox))) for a in shown)
        or any(t.get_rotation() != 0 for t in y_ticks)
    ):
        return _tight_bottom(ax, renderer)
    ax.apply_aspect()  # as the tight box places the frame first (an orbit's equal aspect)
    frame = ax.get_window_extent(renderer)
    measured = ax.xaxis.measuring() if isinstance(ax, ReportAxes) else nullcontext()  # type: ignore[attr-defined]
    with measured:  # the spine's ticks: the axis'
        x_box = ax.xaxis.get_tightbbox(renderer)
        reach = max((t.get_fontsize() for t in y_ticks), default=0.0) * renderer.dpi / 72.0
        if x_box is None or x_box.y0 > frame.y0 - reach:
            return _tight_bottom(ax, renderer)
        others = [*([ax.spines.bottom] if ax.get_frame_on() else []), *ax.texts, ax.get_legend()]
        others += [ax.yaxis.label] if ax.yaxis.get_visible() else []
        boxes = [a.get_tightbbox(renderer) for a in others if a is not None and a.get_visible() and a.get_in_layout()]
    return min(frame.y0, x_box.y0, *(b.y0 for b in boxes if b is not None and (b.width or b.height)))


def _tight_bottom(ax, renderer) -> float | None:
    """The lower edge (px) of matplotlib's tight box of `ax`, None for none."""
    box = ax.get_tightbbox(renderer)
    return None if box is None else box.y0


def _lowest_panels(fig: Figure) -> list:
    """The visible axes of `fig` with no visible axes below them in their columns: a panel's tick
    labels and axis labels reach into the gap under it, never past the panel below, so the lowest
    text is one of these panels' (measuring only them is most of the legend's room saved)."""
    shown = [(ax, ax.get_position()) for ax in fig.axes if ax.get_visible()]
    return [
        ax
        for ax, p in shown
        if not any(q.y1 <= p.y0 and q.x0 < p.x1 and p.x0 < q.x1 for other, q in shown if other is not ax)
    ]


def _panel_ticks(ax) -> None:
    """A journal panel's tick locators: 4 to 6 ticks an axis (matplotlib's 'auto' puts up to 9); in
    a narrow figure at NARROW_STEPS (0.2, 0.4, ...: its quarter steps' labels, 0.25 0.50 0.75, ran
    into each other under a single column's panel at 7 pt)."""
    steps = NARROW_STEPS if narrow.is_narrow(style().width) else TICK_STEPS
    ax.xaxis.set_major_locator(MaxNLocator(nbins=MAX_TICKS, steps=steps))
    ax.yaxis.set_major_locator(MaxNLocator(nbins=MAX_TICKS, steps=steps))


def _empty(fig: Figure) -> None:
    """Remove what was drawn on `fig` (data, legends, titles), the axes kept, as newly made:
    limits found from the data again, colour cycle restarted, and what a figure may set on its
    panels put back (aspect, margins, tick locators), so that a figure of the same shape drawn next
    does not inherit an orbit's equal aspect or a magnitude's ticks kept at zero and above."""
    for legend in list(fig.legends):
        legend.remove()
    for ax in fig.axes:
        for artist in [*ax.lines, *ax.collections, *ax.patches, *ax.texts, *ax.images]:
            artist.remove()
        ax.containers.clear()
        if (ax_legend := ax.get_legend()) is not None:
            ax_legend.remove()
        ax.set_prop_cycle(None)
        ax.set_title("")
        ax.set_xlabel("")
        ax.set_ylabel("")
        ax.set_aspect("auto")
        ax.margins(x=rcParams["axes.xmargin"], y=rcParams["axes.ymargin"])
        _panel_ticks(ax)
        ax.relim()
        ax.set_autoscale_on(True)
