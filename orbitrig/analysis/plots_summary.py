"""The summary figure of a run (matplotlib Agg, no pyplot state): one model's constant K and C
entries at every operating point, beside the simulator's truth; each point named on the x axis
by the conditions that tell the points apart, the conditions they share under the title."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.cbook import is_math_text
from matplotlib.figure import Figure
from matplotlib.font_manager import FontProperties

from orbitrig.analysis.grid import light_grid
from orbitrig.analysis.plots import ENTRIES, TRUTH_LABEL, Fitted, save_figure, entry_k, style
from orbitrig.analysis.plots_coefficients import constant_std
from orbitrig.analysis.typeset import entry_math, lifted_size, operating_point_math, varied
from orbitrig.analysis.plot_panels import figure_legend, max_columns, panels, AXES, panel_figure, clear_y_labels
from orbitrig.analysis.plot_marks import series_colors, keep_min_span, keep_inside, series_look, truth_look
from rigunits import DISPLAY_UNITS
from orbitrig.load_systems import LoadSystem
from orbitrig.store.layout import point_name
from orbitrig.store.stored_run import Settings


#: the x axis: each point by the conditions that differ among the points, as the figures' titles
#: write them (typeset.operating_point_math: ``\u03b5$_\\mathrm{s}$ = 0.1``)
OPERATING_AXIS = "operating point"
#: the x axis of points whose conditions are all alike (a repeated point): each by its number in
#: the run (the page's ``Point 0002``)
POINT_AXIS = "operating point number"
#: the gap (in the tick labels' size) kept between neighbouring tick labels
TICK_GAP = 0.5


def point_ticks(settings: dict[int, Settings]) -> tuple[dict[int, str], str, str]:
    """(each point's tick label, the x axis' label, the conditions every point shares) of the
    points whose settings are `settings` (by index), in mathtext: ``\u03b5$_\\mathrm{s}$ = 0.1`` for
    points that differ in static eccentricity alone; by number (``0002``) where none differ."""
    differ, shared = varied(settings.values())
    common = operating_point_math(next(iter(settings.values())), shared) if settings else ""
    if not differ:
        return {i: point_name(i) for i in settings}, POINT_AXIS, common
    return {i: operating_point_math(s, differ) for i, s in settings.items()}, OPERATING_AXIS, common


def _label_points(fig: Figure, axes, labels: dict[int, str]) -> None:
    """Every point ticked on the (shared) x axis and named by `labels`: side by side while the
    widest label fits between neighbouring points, else upright (90 deg); every k-th point named
    where even upright labels would touch. Labels with subscripts at the size they need
    (typeset.lifted_size), measured as drawn."""
    xs = sorted(labels)
    texts = [labels[i] for i in xs]
    size = max(lifted_size(t, style().small, style().small) for t in texts)
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]  # the Agg canvas of every report figure
    prop = FontProperties(size=size)
    wide = max(renderer.get_text_width_height_descent(t, prop, is_math_text(t))[0] for t in texts) * 72 / fig.dpi
    ax = axes[-1, 0]
    lo, hi = ax.get_xlim()
    step = min(np.diff(xs)) * ax.get_position().width * fig.get_figwidth() * 72.0 / (hi - lo)  # pt between points
    flat = wide + TICK_GAP * size <= step
    every = math.ceil(((wide if flat else 1.2 * size) + TICK_GAP * size) / step)
    ax.set_xticks(xs, [t if n % every == 0 else "" for n, t in enumerate(texts)])  # shared by every panel
    for ax in axes.flat:
        ax.tick_params(axis="x", labelsize=size, labelrotation=0 if flat else 90)


def _space_and_name(fig: Figure, axes, labels: dict[int, str]) -> None:
    """The panels spaced so that a wide tick label (−12.5) keeps each y label clear of the panel
    beside it, and the points named (:func:`_label_points`), the last name inside the figure."""
    clear_y_labels(fig, axes)
    _label_points(fig, axes, labels)
    if _past_right_edge(fig, axes[-1, -1]):  # the panels narrowed to keep it in,
        clear_y_labels(fig, axes)  # their gaps (a share of a panel's width) widened again
        _label_points(fig, axes, labels)


def _past_right_edge(fig: Figure, ax) -> bool:
    """Whether the x tick labels of `ax` (the lowest right panel) reach past the figure's right edge
    (less a gap of TICK_GAP of their size); if so, the panels' right margin is widened by that much
    (a fixed-margin figure; a narrow figure's constrained layout keeps its own room)."""
    if fig.get_layout_engine() is not None:
        return False
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]  # the Agg canvas of every report figure
    box = ax.xaxis.get_tightbbox(renderer)
    gap = TICK_GAP * style().small * fig.dpi / 72.0
    past = 0.0 if box is None else box.x1 + gap - fig.bbox.width
    if past <= 0:
        return False
    fig.subplots_adjust(right=fig.subplotpars.right - past / fig.bbox.width)
    return True


def _summary_panels():
    """(figure, 2 x 4 axes) of the summary; narrow, in at most two columns of panels (plots_narrow)."""
    if max_columns(4) < 4:
        return panels(13, 7.2, 2, 4, bottom=1.5, wspace=0.5)
    fig = panel_figure(13, 7.2, bottom=1.5, wspace=0.5)
    return fig, fig.subplots(2, 4, sharex=True, subplot_kw=AXES)


def summary_plot(
    path,
    series: dict[LoadSystem, list[tuple[int, Fitted]]],
    truth: list[tuple[int, dict]],
    *,
    model: str,
    title: str,
    settings: dict[int, Settings],
) -> Path:
    """:func:`summary_figure` written to `path`."""
    return save_figure(summary_figure(series, truth, model=model, title=title, settings=settings), path)


def summary_figure(
    series: dict[LoadSystem, list[tuple[int, Fitted]]],
    truth: list[tuple[int, dict]],
    *,
    model: str,
    title: str,
    settings: dict[int, Settings],
) -> Figure:
    """The constant K and C entries of one model at every operating point (x: the points in the
    run's order, each named by the conditions that tell the points apart, :func:`point_ticks`, from
    `settings`, each point's by its index; the conditions they share under the title), one marker
    series per load measuring system (its own marker and colour), error bars of U = k u (u on each
    fit's band covariance: combined where the run stored a budget), and the simulator's true values
    (K0, C0) as black crosses."""
    fig, axes = _summary_panels()
    colors = series_colors(len(series))
    offsets = np.linspace(-0.12, 0.12, len(series)) if len(series) > 1 else [0.0]
    largest = {"K": 0.0, "C": 0.0}
    for k, (lms, entries) in enumerate(series.items()):
        idx = np.array([i for i, _ in entries], dtype=float)
        for row, m in enumerate("KC"):
            unit, scale = DISPLAY_UNITS[m]
            for col, e in enumerate(ENTRIES):
                key = m + e
                vals = [f.identification.coefficients.get(key, np.nan) * scale for _, f in entries]
                largest[m] = max(largest[m], float(np.nanmax(np.abs(vals))))
                errs = [entry_k(f, m, e) * constant_std(f, m, e) * scale for _, f in entries]
                look = {"ls": "none", "ms": 4, "capsize": 2, "color": colors[k], **series_look(k)}
                axes[row, col].errorbar(idx + offsets[k], vals, yerr=errs, label=f"{lms}, {model}", **look)
    for row, m in enumerate("KC"):
        unit, scale = DISPLAY_UNITS[m]
        for col, e in enumerate(ENTRIES):
            ax = axes[row, col]
            i, j = divmod(col, 2)
            pts = [(idx, t[f"{m}0"][i][j] * scale) for idx, t in truth if t and f"{m}0" in t]
            if pts:
                ax.plot(*zip(*pts), label=TRUTH_LABEL, **truth_look("large"))
            ax.set_title(entry_math(m + e))
            ax.set_ylabel(f"{entry_math(m + e)}  [{unit}]")  # the quantity with its unit, as the coefficient panels
            light_grid(ax)
            keep_min_span(ax, largest[m])
            if pts:
                xs, ys = zip(*pts)
                keep_inside(ax, xs, ys)
    labels_of, axis, common = point_ticks(settings)
    _space_and_name(fig, axes, labels_of)
    for ax in axes[-1]:
        ax.set_xlabel(axis)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    figure_legend(
        fig,
        handles,
        labels,
        ncols=len(labels),
        title=style().band_label("error bars", [f.basis for entries in series.values() for _, f in entries]),
        fit=True,  # the figure's height fitted to the legend: no empty band above it
    )
    fig.suptitle(f"{title}\nevery point at {common}" if common else title)
    return fig
