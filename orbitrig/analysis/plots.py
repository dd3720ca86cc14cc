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
from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import MaxNLocator

from orbitrig.analysis.reduce import MATRIX_UNITS
from orbitrig.store.durable import write_atomic
from orbitrig.store.errors import storage_error
from reduction.whirl import Whirl

ENTRIES = ("xx", "xy", "yx", "yy")
MATRIX_NAMES = {"K": "stiffness", "C": "damping", "D": "apparent inertia (added mass)"}
PAIR_LABELS = {"xfx": "x, Fx", "yfx": "y, Fx", "xfy": "x, Fy", "yfy": "y, Fy"}
DIRECTIONS = ((1, Whirl.FORWARD, "-", "o"), (-1, Whirl.BACKWARD, "--", "s"))
TRUTH_LABEL = "true (simulator)"
#: zlib level of the PNGs: 1 encodes about twice as fast as the default 6, files about 12 % larger
PNG_COMPRESSION = 1
#: journal column widths (in)
COLUMN_WIDTHS = {"single": 3.5, "double": 7.2}


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

    def band_label(self, what: str = "bands and error bars") -> str:
        """The legend's statement of the uncertainty shown, e.g. 'bands and error bars: expanded
        uncertainty U (k = 2) of the fit (statistical)'."""
        kind = "expanded uncertainty U" if self.coverage != 1 else "standard uncertainty u"
        return f"{what}: \u00b1{kind} (k = {self.coverage:g}), statistical"


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


@dataclass
class Fitted:
    """One identification to draw: a legend label and the Identification object."""

    label: str
    identification: Any  # reduction.identify.Identification


def whirl_direction(table) -> np.ndarray:
    """+1 forward / -1 backward per row, from the phasors (forward: y = -i x)."""
    return np.where(np.imag(np.conj(table.x) * table.y) <= 0, 1, -1)


def _figure(w: float, h: float, layout: str | None = "constrained") -> Figure:
    """A figure on an Agg canvas of the design size w x h (in) scaled to the style's width;
    `layout=None` for many small panels (constrained layout's solver costs seconds there),
    placed by the caller with ``subplots_adjust``."""
    k = STYLE.width / w
    fig = Figure(figsize=(w * k, h * k), dpi=72, layout=layout)
    FigureCanvasAgg(fig)
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
    every tick label. Put the legend with ``loc="lower center"``."""
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
        fig, axes = cache[key]
        _empty(fig)
        return fig, axes
    fig = panel_figure(w, h, **margins)
    axes = np.atleast_2d(fig.subplots(rows, cols, sharex=sharex, squeeze=False))
    cache[key] = fig, axes
    return fig, axes


def _empty(fig: Figure) -> None:
    """Remove what was drawn on `fig` (data, legends, titles), the axes kept, as newly made:
    limits found from the data again, colour cycle restarted."""
    for legend in list(fig.legends):
        legend.remove()
    for ax in fig.axes:
        for artist in [*ax.lines, *ax.collections, *ax.patches, *ax.texts, *ax.images]:
            artist.remove()
        ax.containers.clear()
        if ax.get_legend() is not None:
            ax.get_legend().remove()
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
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise storage_error(path.parent, "create the folder", err) from err
    for fmt in (FigureFormat.PNG, *(f for f in STYLE.formats if f != FigureFormat.PNG)):
        if fmt == FigureFormat.PNG:
            data = png_bytes(fig, STYLE.dpi)
        else:
            buf = io.BytesIO()
            fig.savefig(buf, format=str(fmt), dpi=72, metadata={"Creator": "orbitrig report"})
            data = buf.getbuffer()
        write_atomic(path.with_suffix(f".{fmt}"), data)
    return path


def png_bytes(fig: Figure, dpi: float) -> bytes:
    """`fig` drawn on its Agg canvas at `dpi` and encoded as an RGB PNG (the figure is opaque:
    no alpha channel, so report.pdf can carry the PNG's compressed pixels unchanged)."""
    from PIL import Image

    screen = fig.dpi
    try:
        fig.set_dpi(dpi)
        fig.canvas.draw()
        width, height = fig.canvas.get_width_height(physical=True)
        rgba = Image.frombuffer("RGBA", (width, height), fig.canvas.buffer_rgba(), "raw", "RGBA", 0, 1)  # type: ignore[attr-defined]  # Agg
        buf = io.BytesIO()
        rgba.convert("RGB").save(buf, format="png", dpi=(dpi, dpi), compress_level=PNG_COMPRESSION)
    finally:
        fig.set_dpi(screen)
    return buf.getvalue()


def _colors(n: int) -> list:
    import matplotlib

    cmap = matplotlib.colormaps["tab10"]
    return [cmap(i % 10) for i in range(n)]


def forces_plot(path, table, fitted: Sequence[Fitted], *, title: str) -> Path:
    """:func:`forces_figure` written to `path`."""
    return _save(forces_figure(table, fitted, title=title), path)


def forces_figure(table, fitted: Sequence[Fitted], *, title: str) -> Figure:
    """The paper's Figure 5 with residuals: (top) measured and reproduced force amplitude against
    Omega/omega for Fx and Fy, one line per identification; (bottom) the residual |F_measured -
    F_reproduced| of each fit per frequency, beside the measured phasor's expanded uncertainty
    U = k u (grey) when the table has the phasor uncertainties u_*: a fit whose residuals stay
    under U reproduces the forces within their uncertainty. Error bars on the measured
    amplitude: U/sqrt(2) (the radial part of an isotropic complex error)."""
    fig, axes = panels(11, 9.0, 2, 2, left=1.0, top=1.1, bottom=2.6, hspace=0.3, wspace=0.25)  # legend below
    ratio = table.orbit / table.spin
    dirs = whirl_direction(table)
    colors = _colors(len(fitted))
    k = coverage()
    reproduced = [f.identification.reproduce(table) for f in fitted]
    # models that agree draw on top of each other: each later line is thinner, so all stay visible
    widths = [0.7 + 0.6 * (len(fitted) - 1 - n) for n in range(len(fitted))]
    for col, (name, measured) in enumerate((("Fx", table.fx), ("Fy", table.fy))):
        amp_ax, res_ax = axes[0, col], axes[1, col]
        for d, dname, ls, marker in DIRECTIONS:
            sel = np.flatnonzero(dirs == d)
            if sel.size == 0:
                continue
            sel = sel[np.argsort(ratio[sel])]
            for n, (fit, rep) in enumerate(zip(fitted, reproduced)):
                f = rep[col][sel]
                first = d == 1 or not np.any(dirs == 1)
                amp_ax.plot(
                    ratio[sel], np.abs(f), ls, color=colors[n], lw=widths[n], label=fit.label if first else None
                )
                res_ax.plot(
                    ratio[sel],
                    np.abs(measured[sel] - f),
                    ls,
                    marker=marker,
                    color=colors[n],
                    lw=widths[n],
                    ms=3,
                    mfc=colors[n] if d == 1 else "white",
                )
            face = "black" if d == 1 else "white"
            amp_ax.plot(
                ratio[sel],
                np.abs(measured[sel]),
                marker,
                mfc=face,
                mec="black",
                ls="none",
                ms=4,
                label=f"measured, {dname} whirl",
                zorder=5,
            )
            if table.u is not None:
                u = table.u[sel, 2 + col]
                amp_ax.errorbar(
                    ratio[sel],
                    np.abs(measured[sel]),
                    yerr=k * u / np.sqrt(2.0),
                    fmt="none",
                    ecolor="black",
                    capsize=1.5,
                    lw=0.6,
                    zorder=4,
                    gid="measured-uncertainty",
                )
                res_ax.plot(
                    ratio[sel],
                    k * u,
                    ls,
                    color="0.55",
                    lw=2.2,
                    alpha=0.6,
                    zorder=1,
                    label=f"U = {k:g} u of the measured phasor" if d == 1 or not np.any(dirs == 1) else None,
                    gid="measured-uncertainty",
                )
        amp_ax.set_title(f"{name} amplitude")
        amp_ax.set_ylabel(f"|{name}|  [N]")
        res_ax.set_title(f"{name} residual: |measured - reproduced| phasor")
        res_ax.set_ylabel(f"|\u0394{name}|  [N]")
        res_ax.set_xlabel("\u03a9/\u03c9  [-]")
        res_ax.set_ylim(bottom=0)
        for ax in (amp_ax, res_ax):
            ax.grid(True, alpha=0.3)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    h2, l2 = axes[1, 0].get_legend_handles_labels()
    handles, labels = handles + h2, labels + l2
    if len(set(dirs)) > 1:
        handles += [Line2D([], [], color="gray", ls="-"), Line2D([], [], color="gray", ls="--")]
        labels += ["forward whirl (solid)", "backward whirl (dashed)"]
    ncols = 1 if max(len(label) for label in labels) > 60 else 2  # long labels (verdicts): one column
    fig.legend(
        handles,
        labels,
        loc="lower center",
        ncols=ncols,
        fontsize="small",
        title=style().band_label("error bars") + " (amplitude: U/\u221a2)",
    )
    fig.suptitle(title)
    return fig


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


def summary_plot(
    path, series: dict[str, list[tuple[int, Any]]], truth: list[tuple[int, dict]], *, model: str, title: str
) -> Path:
    """The constant K and C entries of one model at every operating point (x: point
    index), one marker series per load measuring system, error bars of one standard
    error, and the simulator's true values (K0, C0) as black crosses."""
    fig = panel_figure(13, 7.2, bottom=1.5, wspace=0.5)
    axes = fig.subplots(2, 4, sharex=True)
    colors = _colors(len(series))
    offsets = np.linspace(-0.12, 0.12, len(series)) if len(series) > 1 else [0.0]
    largest = {"K": 0.0, "C": 0.0}
    for k, (lms, entries) in enumerate(series.items()):
        idx = np.array([i for i, _ in entries], dtype=float)
        for row, m in enumerate("KC"):
            unit, scale = MATRIX_UNITS[m]
            for col, e in enumerate(ENTRIES):
                key = m + e
                vals = [ident.coefficients.get(key, np.nan) * scale for _, ident in entries]
                largest[m] = max(largest[m], float(np.nanmax(np.abs(vals))))
                errs = [coverage() * (ident.std_errors.get(key) or 0.0) * scale for _, ident in entries]
                axes[row, col].errorbar(
                    idx + offsets[k],
                    vals,
                    yerr=errs,
                    fmt="o",
                    ms=4,
                    capsize=2,
                    color=colors[k],
                    label=f"{lms}, {model}",
                )
    for row, m in enumerate("KC"):
        unit, scale = MATRIX_UNITS[m]
        for col, e in enumerate(ENTRIES):
            ax = axes[row, col]
            i, j = divmod(col, 2)
            pts = [(idx, t[f"{m}0"][i][j] * scale) for idx, t in truth if t and f"{m}0" in t]
            if pts:
                ax.plot(*zip(*pts), "x", color="black", ms=6, mew=1.5, label=TRUTH_LABEL)
            ax.set_title(f"{m}{e}")
            ax.set_ylabel(f"{m}{e}  [{unit}]")
            ax.grid(True, alpha=0.3)
            ax.xaxis.set_major_locator(MaxNLocator(integer=True))
            _min_span(ax, largest[m])
            if pts:
                keep_inside(ax, *zip(*pts))
            if row == 1:
                ax.set_xlabel("operating point  [index]")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(
        handles, labels, loc="lower center", ncols=len(labels), fontsize="small", title=style().band_label("error bars")
    )
    fig.suptitle(title)
    return _save(fig, path)
