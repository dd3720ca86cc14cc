"""What is drawn on a panel of a report figure, whatever its style: fitted curves solid over the
tested whirl range and dotted outside it, uncertainty bands and error bars (added to the data
limits without autoscaling each time), lines made without ``ax.plot``'s argument parsing
(:func:`plot_line`), the whirl direction of each row (+1 forward, -1
backward), curve colours and the marker that tells each series apart in greyscale print, and
axis limits that keep every truth marker inside.
"""

from __future__ import annotations

import numpy as np
from matplotlib import cbook
from matplotlib.axes._base import _process_plot_format  # type: ignore[attr-defined]  # private: not in the stubs
from matplotlib.collections import PolyCollection
from matplotlib.lines import Line2D
from matplotlib.ticker import Locator

#: the marker of each series of a figure, so that a greyscale print tells them apart (truth is
#: :func:`truth_look`'s cross);
#: the next ten series repeat them open (white inside)
SERIES_MARKERS = ("o", "s", "^", "v", "D", "P", "<", ">", "h", "*")
#: markers along a fitted curve: every MARK_STEP of the axes' diagonal, each series starting a
#: little further along, so that the markers of curves lying on each other do not hide each other
MARK_STEP, MARK_SHIFT = 0.12, 0.023


#: the truth crosses' (size, stroke) (pt): "large" beside fitted curves or a few points (impedance,
#: summary), "small" on a coefficient panel, where a cross sits on the fits' markers and error bars
#: at every tested frequency (a larger one hides them)
TRUTH_SIZES = {"large": (6.0, 1.5), "small": (4.0, 1.0)}


def truth_look(where: str, color="black") -> dict:
    """Line2D keywords of the simulator's truth: a cross (no line) of :data:`TRUTH_SIZES` `where`
    ("large", "small") over the fits; black for the point's truth, a fit's colour for its own."""
    ms, mew = TRUTH_SIZES[where]
    return {"marker": "x", "ls": "none", "color": color, "ms": ms, "mew": mew, "zorder": 6}


def series_look(i: int) -> dict:
    """Line2D keywords (marker, marker fill) of the i-th series of a figure (from 0)."""
    marker = SERIES_MARKERS[i % len(SERIES_MARKERS)]
    return {"marker": marker, "mfc": "white"} if (i // len(SERIES_MARKERS)) % 2 else {"marker": marker}


def marks_along(i: int) -> dict:
    """Line2D keywords of the i-th series' curve: its marker (:func:`series_look`), every
    MARK_STEP of the axes' diagonal, from its own start."""
    return {**series_look(i), "ms": 3.0, "markevery": ((i * MARK_SHIFT) % MARK_STEP, MARK_STEP)}


def tested_range(orbit) -> tuple[float, float]:
    """(lowest, highest) tested |Omega| (rad/s): fits are drawn solid only between them."""
    w = np.abs(np.asarray(orbit, dtype=float))
    return float(w.min()), float(w.max())


def split_tested(grid: np.ndarray, lo: float, hi: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Boolean masks of `grid` below, inside and above the tested range (the edges in both
    neighbours, so the solid and dashed parts join)."""
    eps = 1e-9 * max(hi, 1.0)
    return grid <= lo + eps, (grid >= lo - eps) & (grid <= hi + eps), grid >= hi - eps


def plot_line(ax, x: np.ndarray, y: np.ndarray, fmt: str | None = None, **kw):
    """``ax.plot(x, y, fmt, **kw)`` of one line (x, y: 1-d, of the same length, in numbers): the
    Line2D ax.plot makes (the format's line style, marker and colour under `kw`, the property
    cycle's next entry where `kw` leaves one of its keys unset), added and autoscaled as ax.plot
    adds it, without its parsing of arguments and data (a quarter of its time)."""
    kw = cbook.normalize_kwargs(kw, Line2D)
    if fmt is not None:
        style = zip(("linestyle", "marker", "color"), _process_plot_format(fmt))
        kw = {**{k: v for k, v in style if v is not None}, **kw}
    for k, v in ax._get_lines._prop_cycle.getdefaults(kw).items():  # as ax.plot: the cycle advanced
        if kw.get(k) is None:
            kw[k] = v
    made = ax.add_line(Line2D(np.asarray(x), np.asarray(y), **kw))
    ax._request_autoscale_view("x")
    ax._request_autoscale_view("y")
    return made


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
    marks: dict | None = None,
) -> None:
    """A fitted curve y(x), x = Omega/omega: `ls` over the tested range [lo, hi] (same units as
    x), with `marks` (Line2D keywords: :func:`marks_along`), thin dotted outside it (an
    extrapolation, not a result)."""
    below, inside, above = split_tested(x, lo, hi)
    plot_line(ax, x[inside], y[inside], ls, color=color, lw=lw, label=label, **(marks or {}))
    for part in (below, above):
        if part.sum() > 1:
            plot_line(ax, x[part], y[part], ":", color=color, lw=0.7 * lw)


def band(ax, x: np.ndarray, lo: np.ndarray, hi: np.ndarray, *, color, alpha: float = 0.15) -> None:
    """Shade lo..hi over x, as ``fill_between`` does, without its cost: fill_between finds the
    band's data limits through the axes' transform, which autoscales every axes sharing x
    after each band; here the limits are added as data and the axes scale once when drawn."""
    verts = np.column_stack([np.r_[x, x[::-1]], np.r_[lo, hi[::-1]]])
    ax.add_collection(PolyCollection([verts], facecolors=[color], alpha=alpha, linewidths=0), autolim=False)
    _add_limits(ax, verts)


def error_bars(
    ax,
    x: np.ndarray,
    y: np.ndarray,
    err: np.ndarray,
    *,
    color,
    ms: float,
    capsize: float,
    lw: float,
    look: dict | None = None,
) -> None:
    """Markers at (x, y) (`look`: Line2D keywords of :func:`series_look`, else filled circles)
    with vertical bars y +- err and caps (capsize: half-width, pt), as ``errorbar`` draws them,
    the bars a LineCollection (see :func:`band`)."""
    ax.vlines(x, y - err, y + err, colors=[color], linewidths=lw)
    plot_line(ax, x, y, ls="none", ms=ms, color=color, **(look or {"marker": "o"}))
    plot_line(ax, np.r_[x, x], np.r_[y - err, y + err], "_", ms=2 * capsize, mew=lw, color=color)


def _add_limits(ax, xy: np.ndarray) -> None:
    ok = np.all(np.isfinite(xy), axis=1)
    if ok.any():
        ax.update_datalim(xy[ok])
        ax._request_autoscale_view()


def whirl_direction(table) -> np.ndarray:
    """+1 forward / -1 backward per row, from the phasors (forward: y = -i x)."""
    return np.where(np.imag(np.conj(table.x) * table.y) <= 0, 1, -1)


def series_colors(n: int) -> list:
    """One colour per series, ``n`` of them: matplotlib's tab10 in order (RGBA tuples, 0..1),
    the eleventh series again in the first's."""
    import matplotlib

    cmap = matplotlib.colormaps["tab10"]
    return [cmap(i % 10) for i in range(n)]


def keep_min_span(ax, largest: float, fraction: float = 0.05) -> None:
    """Make the y axis span at least `fraction` of the matrix's largest entry (`largest` in the
    axis's own unit), so that differences far inside the 5 % criterion do not fill a coefficient panel."""
    lo, hi = ax.get_ylim()
    if hi - lo < fraction * largest:
        mid = (lo + hi) / 2
        ax.set_ylim(mid - fraction / 2 * largest, mid + fraction / 2 * largest)


class _NonNegative(Locator):
    """The ticks of `base` (the panel's locator), none below zero: a magnitude's axis."""

    def __init__(self, base: Locator):
        self.base = base

    def set_axis(self, axis) -> None:
        super().set_axis(axis)
        self.base.set_axis(axis)

    def __call__(self):
        return self.tick_values(*self.axis.get_view_interval())

    def tick_values(self, vmin, vmax):
        ticks = np.asarray(self.base.tick_values(vmin, vmax))
        return ticks[ticks >= -1e-12 * max(abs(vmin), abs(vmax))]


def from_zero(ax) -> None:
    """A magnitude's y axis: zero near its bottom with the data's room (plots.DATA_ROOM: the axes'
    y margin) below it for the markers at zero, and none of its ticks below zero."""
    top = ax.get_ylim()[1]
    ax.set_ylim(-ax.margins()[1] * top, top)
    if not isinstance(locator := ax.yaxis.get_major_locator(), _NonNegative):  # a reused panel has it
        ax.yaxis.set_major_locator(_NonNegative(locator))


def keep_inside(ax, xs, ys) -> None:
    """Widen the axes limits so that every point (xs, ys) lies inside, with the axes' own margins
    (plots.DATA_ROOM for y) of the span to spare: truth markers must never fall outside the panel."""
    xs, ys = np.asarray(xs, dtype=float).ravel(), np.asarray(ys, dtype=float).ravel()
    ok = np.isfinite(xs) & np.isfinite(ys)
    if not ok.any():
        return
    sides = ((xs[ok], ax.get_xlim, ax.set_xlim), (ys[ok], ax.get_ylim, ax.set_ylim))
    for (lim, get, put), margin in zip(sides, ax.margins()):
        lo, hi = get()
        span = max(hi - lo, float(np.ptp(lim)), 1e-12)
        if lim.min() <= lo or lim.max() >= hi:
            put(min(lo, lim.min() - margin * span), max(hi, lim.max() + margin * span))
