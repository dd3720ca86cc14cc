"""Figures of one operating point (matplotlib, Agg canvas, no pyplot state).

Every figure takes plain data (an OrbitTable, Identification objects from
``reduction.identify``, the point's settings and truth) and is written as a 300 dpi PNG (RGB,
no alpha: report.pdf embeds its pixels as they are), optionally beside a vector PDF and SVG of
the same name (:class:`FigureStyle`: formats, the journal width, the coverage factor of every
band and error bar). Axes carry units at the edges: Omega/omega
(-), N, deg, MN/m, kN s/m, kg. Forward whirl is drawn with filled markers and solid lines,
backward whirl with open markers and dashed lines.
"""

from __future__ import annotations

import io
import threading
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path
from collections.abc import Iterable
from typing import Any, Literal

import numpy as np
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from orbitrig.analysis import plots_narrow as narrow
from orbitrig.analysis.canvas import ReportCanvas, png_bytes
from orbitrig.analysis.report_axes import ReportAxes
from orbitrig.store.durable import write_atomic
from orbitrig.store.errors import storage_error
from reduction.systematic import UncertaintyBasis
from reduction.whirl import Whirl

ENTRIES = ("xx", "xy", "yx", "yy")
MATRIX_NAMES = {"K": "stiffness", "C": "damping", "D": "apparent inertia (added mass)"}
PAIR_LABELS = {"xfx": "x, Fx", "yfx": "y, Fx", "xfy": "x, Fy", "yfy": "y, Fy"}
DIRECTIONS = ((1, Whirl.FORWARD, "-", "o"), (-1, Whirl.BACKWARD, "--", "s"))
TRUTH_LABEL = "true (simulator)"
#: ticks of each panel axis: at most MAX_TICKS intervals, at 1, 2, 2.5 or 5 times a power of 10
MAX_TICKS = 5
TICK_STEPS = (1, 2, 2.5, 5, 10)
#: journal column widths (in)
COLUMN_WIDTHS = {"single": 3.5, "double": 7.2}
#: keyword arguments of every report figure's ``subplots``: axes that measure tick labels once per draw
AXES = {"axes_class": ReportAxes}
#: the room (pt) a figure's legend keeps below the lowest tick labels and axis labels of its panels
LEGEND_GAP = 4.0


class FigureFormat(StrEnum):
    PNG = "png"
    PDF = "pdf"
    SVG = "svg"


@dataclass(frozen=True)
class FigureStyle:
    """How every figure of a report is drawn and written: ``width`` (in; the journal's double
    column by default), ``formats`` (PNG for the page; PDF and SVG, vector, for print: each
    costs about as much as the PNG again, so they are asked for), PNG resolution (dpi), the text size at that width (pt) and the coverage factor k of every
    band and error bar (2: the expanded uncertainty U = k u)."""

    width: float = COLUMN_WIDTHS["double"]
    formats: tuple[FigureFormat, ...] = (FigureFormat.PNG,)
    dpi: int = 300
    font: float = 6.5
    coverage: float = 2.0

    def band_label(
        self, what: str = "bands and error bars", bases: Iterable[UncertaintyBasis] = (UncertaintyBasis.STATISTICAL,)
    ) -> str:
        """The legend's statement of the uncertainty shown, e.g. 'bands and error bars: expanded
        uncertainty U (k = 2), statistical'; `bases`: what the u of the fits shown rests on (the
        derived quantities' is combined where the run stored a calibration budget)."""
        kind = "expanded uncertainty U" if self.coverage != 1 else "standard uncertainty u"
        shown = set(bases)
        words = " or ".join(BAND_BASIS[b] for b in UncertaintyBasis if b in shown)
        return f"{what}: \u00b1{kind} (k = {self.coverage:g}), {words}"


#: the legend's words for what a band's standard uncertainty rests on
BAND_BASIS = {
    UncertaintyBasis.COMBINED: "combined (statistical and calibration)",
    UncertaintyBasis.STATISTICAL: "statistical",
}


STYLE = FigureStyle()


def use_style(style: FigureStyle) -> None:
    """Draw every later figure of this process in `style` (text sizes through rcParams)."""
    import matplotlib

    global STYLE
    STYLE = style
    matplotlib.rcParams.update(
        {
            "font.size": style.font,
            "axes.titlesize": "medium",
            "axes.labelsize": "medium",
            "xtick.labelsize": "small",
            "ytick.labelsize": "small",
            "legend.fontsize": "small",
            "figure.titlesize": "large",
            "lines.linewidth": 1.0,
            "lines.markersize": 3.5,
            "pdf.fonttype": 42,
            "svg.fonttype": "none",
            "path.simplify": True,
            "axes.titley": 1.0,  # titles at a fixed height: no search for overlapping tick labels per draw
        }
    )


def style() -> FigureStyle:
    """The style figures are drawn in now (:func:`use_style`)."""
    return STYLE


def coverage() -> float:
    """The coverage factor k of the current style (bands are +-k u)."""
    return STYLE.coverage


use_style(STYLE)


def tested_range(orbit) -> tuple[float, float]:
    """(lowest, highest) tested |Omega| (rad/s): fits are drawn solid only between them."""
    w = np.abs(np.asarray(orbit, dtype=float))
    return float(w.min()), float(w.max())


def split_tested(grid: np.ndarray, lo: float, hi: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Boolean masks of `grid` below, inside and above the tested range (the edges in both
    neighbours, so the solid and dashed parts join)."""
    eps = 1e-9 * max(hi, 1.0)
    return grid <= lo + eps, (grid >= lo - eps) & (grid <= hi + eps), grid >= hi - eps


def plot_fit(
    ax,
    x: np.ndarray,
    y: np.ndarray,
    lo: float,
    hi: float,
    *,
    color,
    lw: float = 1.2,
    label: str | None = None,
    ls: str = "-",
) -> None:
    """A fitted curve y(x), x = Omega/omega: `ls` over the tested range [lo, hi] (same units as
    x), thin dotted outside it (an extrapolation, not a result)."""
    below, inside, above = split_tested(x, lo, hi)
    ax.plot(x[inside], y[inside], ls, color=color, lw=lw, label=label)
    for part in (below, above):
        if part.sum() > 1:
            ax.plot(x[part], y[part], ":", color=color, lw=0.7 * lw)


def band(ax, x: np.ndarray, lo: np.ndarray, hi: np.ndarray, *, color, alpha: float = 0.15) -> None:
    """Shade lo..hi over x, as ``fill_between`` does, without its cost: fill_between finds the
    band's data limits through the axes' transform, which autoscales every axes sharing x
    after each band; here the limits are added as data and the axes scale once when drawn."""
    verts = np.column_stack([np.r_[x, x[::-1]], np.r_[lo, hi[::-1]]])
    ax.add_collection(PolyCollection([verts], facecolors=[color], alpha=alpha, linewidths=0), autolim=False)
    _add_limits(ax, verts)


def error_bars(
    ax, x: np.ndarray, y: np.ndarray, err: np.ndarray, *, color, ms: float, capsize: float, lw: float
) -> None:
    """Markers at (x, y) with vertical bars y +- err and caps (capsize: half-width, pt), as
    ``errorbar(fmt="o")`` draws them, the bars a LineCollection (see :func:`band`)."""
    ax.vlines(x, y - err, y + err, colors=[color], linewidths=lw)
    ax.plot(x, y, "o", ms=ms, color=color)
    ax.plot(np.r_[x, x], np.r_[y - err, y + err], "_", ms=2 * capsize, mew=lw, color=color)


def _add_limits(ax, xy: np.ndarray) -> None:
    ok = np.all(np.isfinite(xy), axis=1)
    if ok.any():
        ax.update_datalim(xy[ok])
        ax._request_autoscale_view()


@dataclass
class Fitted:
    """One identification to draw: a legend label, the Identification object and, in simulator
    runs, its own truth (coefficient -> true value: the true Z projected onto its model)."""

    label: str
    identification: Any  # reduction.identify.Identification
    truth: dict[str, float] | None = None


def whirl_direction(table) -> np.ndarray:
    """+1 forward / -1 backward per row, from the phasors (forward: y = -i x)."""
    return np.where(np.imag(np.conj(table.x) * table.y) <= 0, 1, -1)


def _figure(w: float, h: float, layout: Literal["constrained", "compressed", "tight"] | None = "constrained") -> Figure:
    """A figure on an Agg canvas of the design size w x h (in) scaled to the style's width;
    `layout=None` for many small panels (constrained layout's solver costs seconds there),
    placed by the caller with ``subplots_adjust``."""
    k = STYLE.width / w
    fig = Figure(figsize=(w * k, h * k), dpi=72, layout=layout)
    ReportCanvas(fig)
    return fig


def text_scale() -> float:
    """Margins drawn for 10-pt text, scaled to the style's text size."""
    return STYLE.font / 10.0


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
    if narrow.is_narrow(STYLE.width):
        return _figure(w, h)
    fig = _figure(w, h, layout=None)
    t = text_scale() * w / STYLE.width  # margins in design inches, for the style's text
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
    key = (w, h, rows, cols, sharex, tuple(sorted(margins.items())), STYLE)
    cache = _PANELS.__dict__.setdefault("figures", {})
    if key in cache:
        fig, axes, size, margins_now = cache[key]
        _empty(fig)
        if tuple(fig.get_size_inches()) != size:  # grown for a long legend (_room_below)
            fig.set_size_inches(*size)
            fig.subplots_adjust(bottom=margins_now[0], top=margins_now[1])
        return fig, axes
    if narrow.is_narrow(STYLE.width):  # fewer columns of panels, a taller figure
        t = text_scale() * (margins.get("top", 0.95) + margins.get("bottom", 1.15))
        h = narrow.height(w, h, rows, cols, STYLE.width, t)
    fig = panel_figure(w, h, **margins)
    axes = narrow.grid_axes(fig, rows, cols, sharex=sharex, subplot_kw=AXES, width=STYLE.width)
    for ax in axes.flat:  # a journal panel reads 4 to 6 ticks an axis (matplotlib's 'auto' puts up to 9)
        ax.xaxis.set_major_locator(MaxNLocator(nbins=MAX_TICKS, steps=TICK_STEPS))
        ax.yaxis.set_major_locator(MaxNLocator(nbins=MAX_TICKS, steps=TICK_STEPS))
    cache[key] = fig, axes, tuple(fig.get_size_inches()), (fig.subplotpars.bottom, fig.subplotpars.top)
    return fig, axes


def max_columns(cols: int) -> int:
    """How many of `cols` columns of panels a figure of the style's width shows side by side."""
    return narrow.columns(cols, STYLE.width)


def figure_legend(fig: Figure, handles: list, labels: list, **kw: Any):
    """The legend under a figure's panels: ``fig.legend(handles, labels, loc="lower center", ...)``
    in the margin the figure leaves it; in a narrow figure wrapped to its width, outside the
    panels (plots_narrow.figure_legend)."""
    if narrow.is_narrow(STYLE.width):
        return narrow.figure_legend(fig, handles, labels, **kw)
    legend = fig.legend(handles, labels, **{"loc": "lower center", **kw})
    _room_below(fig, legend)
    return legend


def _room_below(fig: Figure, legend) -> None:
    """Grow `fig` at the bottom until `legend` (on its lower edge) clears every panel, tick label
    and axis label by LEGEND_GAP (pt): the panels keep their size and their place from the top,
    however many entries the legend has. (:func:`panels` gives a reused figure its size back.)"""
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]  # the Agg canvas of every report figure
    boxes = [ax.get_tightbbox(renderer) for ax in fig.axes if ax.get_visible()]
    lowest = min((b.y0 for b in boxes if b is not None), default=None)
    if lowest is None:
        return
    overlap = legend.get_window_extent(renderer).y1 + LEGEND_GAP * fig.dpi / 72.0 - lowest  # pixels
    if overlap <= 0:
        return
    w, h = fig.get_size_inches()
    grow = overlap / fig.dpi  # in
    bottom, top = fig.subplotpars.bottom, fig.subplotpars.top
    fig.set_size_inches(w, h + grow)
    fig.subplots_adjust(bottom=(bottom * h + grow) / (h + grow), top=(top * h + grow) / (h + grow))


def _empty(fig: Figure) -> None:
    """Remove what was drawn on `fig` (data, legends, titles), the axes kept, as newly made:
    limits found from the data again, colour cycle restarted."""
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
        ax.relim()
        ax.set_autoscale_on(True)


def save_figure(fig: Figure, path: Path) -> Path:
    """Write `fig` to `path` (.png) and beside it in the style's other formats (folders
    created); returns the PNG's path."""
    return _save(fig, path)


def _save(fig: Figure, path: Path) -> Path:
    """Each of the style's formats rendered in memory, then written durably (a StorageError
    names the file); returns the PNG's path."""
    path = Path(path).with_suffix(".png")
    if narrow.is_narrow(STYLE.width):
        narrow.fit_texts(fig)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise storage_error(path.parent, "create the folder", err) from err
    for fmt in (FigureFormat.PNG, *(f for f in STYLE.formats if f != FigureFormat.PNG)):
        if fmt == FigureFormat.PNG:
            data: bytes | memoryview = png_bytes(fig, STYLE.dpi)
        else:
            buf = io.BytesIO()
            fig.savefig(buf, format=str(fmt), dpi=72, metadata={"Creator": "orbitrig report"})
            data = buf.getbuffer()
        write_atomic(path.with_suffix(f".{fmt}"), data)
    return path


def _colors(n: int) -> list:
    import matplotlib

    cmap = matplotlib.colormaps["tab10"]
    return [cmap(i % 10) for i in range(n)]


def _min_span(ax, largest: float, fraction: float = 0.05) -> None:
    """Make the y axis span at least `fraction` of the matrix's largest entry, so
    that differences far inside the 5 % criterion do not fill a coefficient panel."""
    lo, hi = ax.get_ylim()
    if hi - lo < fraction * largest:
        mid = (lo + hi) / 2
        ax.set_ylim(mid - fraction / 2 * largest, mid + fraction / 2 * largest)


def keep_inside(ax, xs, ys, margin: float = 0.05) -> None:
    """Widen the axes limits so that every point (xs, ys) lies inside, with `margin` of the
    span to spare: truth markers must never fall outside the panel."""
    xs, ys = np.asarray(xs, dtype=float).ravel(), np.asarray(ys, dtype=float).ravel()
    ok = np.isfinite(xs) & np.isfinite(ys)
    if not ok.any():
        return
    for lim, get, put in ((xs[ok], ax.get_xlim, ax.set_xlim), (ys[ok], ax.get_ylim, ax.set_ylim)):
        lo, hi = get()
        span = max(hi - lo, float(np.ptp(lim)), 1e-12)
        if lim.min() <= lo or lim.max() >= hi:
            put(min(lo, lim.min() - margin * span), max(hi, lim.max() + margin * span))
