"""The paper's Figure 5 with residuals (matplotlib Agg, no pyplot state): measured and reproduced
force amplitude against Omega/omega, and each fit's residual beside the measured phasor's
expanded uncertainty."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from orbitrig.analysis import plots_narrow as narrow
from orbitrig.analysis.grid import light_grid
from orbitrig.analysis.plots import DIRECTIONS, Fitted, save_figure, coverage, style
from orbitrig.analysis.plot_panels import figure_legend, panels
from orbitrig.analysis.plot_marks import series_colors, from_zero, plot_line, series_look, whirl_direction
from orbitrig.analysis.typeset import force_math


def forces_plot(path, table, fitted: Sequence[Fitted], *, title: str) -> Path:
    """:func:`forces_figure` written to `path`."""
    return save_figure(forces_figure(table, fitted, title=title), path)


def forces_figure(table, fitted: Sequence[Fitted], *, title: str) -> Figure:
    """The paper's Figure 5 with residuals: (top) measured and reproduced force amplitude against
    Omega/omega for Fx and Fy, one line per identification; (bottom) the residual |F_measured -
    F_reproduced| of each fit per frequency, beside the measured phasor's expanded uncertainty
    U = k u (grey) when the table has the phasor uncertainties u_*: a fit whose residuals stay
    under U reproduces the forces within their uncertainty. Error bars on the measured
    amplitude: U/sqrt(2) (the radial part of an isotropic complex error)."""
    fig, axes = panels(11, 9.0, 2, 2, left=1.0, top=1.1, bottom=2.6, hspace=0.3, wspace=0.25)  # legend below
    dirs = whirl_direction(table)
    reproduced = [f.identification.reproduce(table) for f in fitted]
    for col, name in enumerate(map(force_math, "xy")):
        amp_ax, res_ax = axes[0, col], axes[1, col]
        for d, dname, ls, marker in DIRECTIONS:
            sel = np.flatnonzero(dirs == d)
            if sel.size:
                first = d == 1 or not np.any(dirs == 1)  # the direction whose lines carry the legend
                _draw_direction(amp_ax, res_ax, table, fitted, reproduced, col, sel, (dname, ls, marker), first)
        amp_ax.set_title(f"{name} amplitude")
        amp_ax.set_ylabel(f"|{name}|  [N]")
        res_ax.set_title(f"{name} residual: |measured \u2212 reproduced| phasor")
        res_ax.set_ylabel(f"|\u0394{name}|  [N]")
        res_ax.set_xlabel("\u03a9/\u03c9  [-]")
        from_zero(res_ax)
        for ax in (amp_ax, res_ax):
            light_grid(ax)
    _legend(fig, axes, both_directions=len(set(dirs)) > 1)
    fig.suptitle(title)
    return fig


def _draw_direction(amp_ax, res_ax, table, fitted, reproduced, col: int, sel, look, first: bool) -> None:
    """One whirl direction of force `col` (0: Fx, 1: Fy): the fits' amplitudes and residuals,
    the measured amplitude with its error bars and the residuals' yardstick U."""
    dname, ls, marker = look
    ratio = table.orbit / table.spin
    sel = sel[np.argsort(ratio[sel])]
    x = ratio[sel]
    measured = (table.fx, table.fy)[col][sel]
    forward = ls == "-"
    colors = series_colors(len(fitted))
    # models that agree draw on top of each other: each later line is thinner, so all stay visible,
    # and each fit has its own marker (filled forward, open backward) for a greyscale print
    widths = [0.7 + 0.6 * (len(fitted) - 1 - n) for n in range(len(fitted))]
    for n, (fit, rep) in enumerate(zip(fitted, reproduced)):
        f = rep[col][sel]
        line = {**series_look(n), "color": colors[n], "lw": widths[n], "ms": 3}
        if not forward:
            line["mfc"] = "white"
        plot_line(amp_ax, x, np.abs(f), ls, label=fit.label if first else None, **line)
        plot_line(res_ax, x, np.abs(measured - f), ls, **line)
    face = "black" if forward else "white"
    label: str | None = f"measured, {dname} whirl"
    plot_line(amp_ax, x, np.abs(measured), marker, mfc=face, mec="black", ls="none", ms=4, label=label, zorder=5)
    if table.u is None:
        return
    k, u = coverage(), table.u[sel, 2 + col]
    bars = {"fmt": "none", "ecolor": "black", "capsize": 1.5, "lw": 0.6, "zorder": 4, "gid": "measured-uncertainty"}
    amp_ax.errorbar(x, np.abs(measured), yerr=k * u / np.sqrt(2.0), **bars)
    label = f"U = {k:g} u of the measured phasor" if first else None
    plot_line(res_ax, x, k * u, ls, color="0.55", lw=2.2, alpha=0.6, zorder=1, label=label, gid="measured-uncertainty")


def _legend(fig, axes, *, both_directions: bool) -> None:
    """One legend under the panels: fits, measurements, the yardstick and the line styles, in two
    columns unless the figure is narrow, the figure's height fitted to it (no empty band between)."""
    handles, labels = axes[0, 0].get_legend_handles_labels()
    h2, l2 = axes[1, 0].get_legend_handles_labels()
    handles, labels = handles + h2, labels + l2
    if both_directions:
        handles += [Line2D([], [], color="gray", ls="-"), Line2D([], [], color="gray", ls="--")]
        labels += ["forward whirl (solid)", "backward whirl (dashed)"]
    # two columns where the figure is wide: one column of long labels (verdicts) left bands beside it;
    # a narrow figure wraps each label to its width (plots_narrow), long ones to one column
    long = max(len(label) for label in labels) > 60
    ncols = 1 if long and narrow.is_narrow(style().width) else 2
    figure_legend(
        fig,
        handles,
        labels,
        ncols=ncols,
        title=style().band_label("error bars") + " (amplitude: U/\u221a2)",
        fit=True,
    )
