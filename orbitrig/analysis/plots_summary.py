"""The summary figure of a run (matplotlib Agg, no pyplot state): one model's constant K and C
entries at every operating point, beside the simulator's truth."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from orbitrig.analysis.grid import light_grid
from orbitrig.analysis.plots import ENTRIES, TRUTH_LABEL, Fitted, _save, coverage, style
from orbitrig.analysis.plots_coefficients import constant_std
from orbitrig.analysis.typeset import entry_math
from orbitrig.analysis.plot_panels import figure_legend, max_columns, panels, AXES, panel_figure
from orbitrig.analysis.plot_marks import _colors, _min_span, keep_inside, series_look, truth_look
from rigunits import DISPLAY_UNITS
from orbitrig.load_systems import LoadSystem


#: the x axis: each point by its number in the run (the page's ``Point 0002``), a count without a
#: unit; a point's conditions (typeset.operating_point_math) are too long for a tick label
POINT_AXIS = "operating point number"


def _summary_panels():
    """(figure, 2 x 4 axes) of the summary; narrow, in at most two columns of panels (plots_narrow)."""
    if max_columns(4) < 4:
        return panels(13, 7.2, 2, 4, bottom=1.5, wspace=0.5)
    fig = panel_figure(13, 7.2, bottom=1.5, wspace=0.5)
    return fig, fig.subplots(2, 4, sharex=True, subplot_kw=AXES)


def summary_plot(
    path, series: dict[LoadSystem, list[tuple[int, Fitted]]], truth: list[tuple[int, dict]], *, model: str, title: str
) -> Path:
    """:func:`summary_figure` written to `path`."""
    return _save(summary_figure(series, truth, model=model, title=title), path)


def summary_figure(
    series: dict[LoadSystem, list[tuple[int, Fitted]]], truth: list[tuple[int, dict]], *, model: str, title: str
) -> Figure:
    """The constant K and C entries of one model at every operating point (x: the point's number
    in the run, as the page numbers them), one marker series per load measuring system (its own
    marker and colour), error bars of U = k u (u on each fit's band covariance: combined where the
    run stored a budget), and the simulator's true values (K0, C0) as black crosses."""
    fig, axes = _summary_panels()
    colors = _colors(len(series))
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
                errs = [coverage() * constant_std(f, m, e) * scale for _, f in entries]
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
            ax.xaxis.set_major_locator(MaxNLocator(integer=True))
            _min_span(ax, largest[m])
            if pts:
                xs, ys = zip(*pts)
                keep_inside(ax, xs, ys)
            if row == 1:
                ax.set_xlabel(POINT_AXIS)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    figure_legend(
        fig,
        handles,
        labels,
        ncols=len(labels),
        title=style().band_label("error bars", [f.basis for entries in series.values() for _, f in entries]),
    )
    fig.suptitle(title)
    return fig
