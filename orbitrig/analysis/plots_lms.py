"""The two load measuring systems side by side (matplotlib Agg, no pyplot state): piezoelectric
minus strain-gauge force relative to piezoelectric per frequency (load_systems.DIFFERENCE), and
the constant K and C identified from each;
Fx and Fy told apart by colour and marker, the systems' bars by colour and hatch, one legend
under the panels."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from orbitrig.analysis import plots_narrow as narrow
from orbitrig.analysis.grid import light_grid
from orbitrig.analysis.plots import DIRECTIONS, ENTRIES, MATRIX_NAMES, Fitted, save_figure, entry_k, style
from orbitrig.analysis.plot_panels import figure_legend, panels
from orbitrig.analysis.plots_coefficients import constant_std
from orbitrig.analysis.plot_marks import series_colors, whirl_direction
from orbitrig.analysis.typeset import entry_math, force_math
from rigunits import DISPLAY_UNITS
from orbitrig.load_systems import DIFFERENCE, DIFFERENCE_WORDS, LoadSystem, relative_difference

#: Fy's markers by whirl direction (+1, -1), where Fx has plots.DIRECTIONS' circles and squares
FY_MARKERS = {1: "^", -1: "v"}
#: the hatch of each load measuring system's bars (a greyscale print tells them apart)
BAR_HATCHES = ("", "////")


def lms_comparison_plot(
    path, tables: dict[LoadSystem, Any], fitted: dict[LoadSystem, Fitted] | None, *, title: str
) -> Path:
    """The two load measuring systems side by side: piezoelectric minus strain-gauge force
    relative to piezoelectric (amplitude difference in %, phase difference in deg) per
    frequency, and the constant K and C of one identification from each."""
    with_bars = fitted is not None and len(fitted) == 2
    rows = 2 if with_bars else 1
    fig, axes = panels(12, 7.5 if with_bars else 4.2, rows, 2, sharex=False, left=1.0, top=1.1, bottom=0.8, hspace=0.6)
    _differences(axes[0], *(tables[lms] for lms in DIFFERENCE))
    legend_title = None
    if with_bars:
        assert fitted is not None
        _coefficient_bars(axes[1], fitted)
        legend_title = style().band_label("error bars", [f.basis for f in fitted.values()])
    entries: dict[str, Any] = {}  # one legend under the panels: none covers data
    for ax in axes.flat:
        handles, labels = ax.get_legend_handles_labels()
        entries |= dict(zip(labels, handles))
    figure_legend(fig, list(entries.values()), list(entries), ncols=3, title=legend_title)
    fig.suptitle(title)
    return save_figure(fig, path)


def _differences(axes, a, b) -> None:
    """`a` minus `b` (load_systems.DIFFERENCE: piezo − strain, relative to |piezo|, as the page's
    consistency table) per frequency: amplitude difference (%) in axes[0], phase (deg) in axes[1]."""
    ratio = a.orbit / a.spin
    dirs = whirl_direction(a)
    colors = series_colors(2)
    for c, (name, fa, fb) in enumerate(((force_math("x"), a.fx, b.fx), (force_math("y"), a.fy, b.fy))):
        amplitude, phase = relative_difference(fa, fb)
        for d, dname, ls, marker in DIRECTIONS:
            sel = np.flatnonzero(dirs == d)
            if sel.size == 0:
                continue
            sel = sel[np.argsort(ratio[sel])]
            marker = marker if c == 0 else FY_MARKERS[d]
            look = {"ls": ls, "marker": marker, "color": colors[c], "mfc": colors[c] if d == 1 else "white"}
            axes[0].plot(ratio[sel], 100 * amplitude[sel], label=f"{name}, {dname}", **look)
            axes[1].plot(ratio[sel], np.degrees(phase[sel]), label=f"{name}, {dname}", **look)
    first, second = DIFFERENCE
    axes[0].set_ylabel(f"(|F {first}| \u2212 |F {second}|)\n/ |F {first}|  [%]")  # two lines, as the phase's
    words = DIFFERENCE_WORDS.replace(" ", "\u00a0")  # wrapped as one word in a single column's panel
    words = ("\n" if narrow.is_narrow(style().width) else " ") + words  # narrow: both titles on two lines
    axes[0].set_title(f"amplitude:{words}")
    axes[1].set_ylabel(f"phase(F {first}) \u2212\nphase(F {second})  [deg]")  # two lines: a narrow panel's height
    axes[1].set_title(f"phase:{words}")
    for ax in axes:
        ax.set_xlabel("\u03a9/\u03c9  [-]")
        ax.axhline(0, color="gray", lw=0.8)
        light_grid(ax)


def _coefficient_bars(axes, fitted: dict[LoadSystem, Fitted]) -> None:
    """The constant K (axes[0]) and C (axes[1]) identified from each system, with error bars of U
    on each fit's band covariance (combined where the run stored a budget), as the other figures."""
    width = 0.38
    colors = series_colors(2)
    for col, m in enumerate("KC"):
        ax = axes[col]
        unit, scale = DISPLAY_UNITS[m]
        keys = [m + e for e in ENTRIES]
        for k, (lms, fit) in enumerate(fitted.items()):
            ident = fit.identification
            vals = [ident.coefficients.get(key, np.nan) * scale for key in keys]
            errs = [entry_k(fit, m, e) * constant_std(fit, m, e) * scale for e in ENTRIES]
            x = np.arange(4) + (k - 0.5) * width
            look = {"color": colors[k], "hatch": BAR_HATCHES[k % len(BAR_HATCHES)], "edgecolor": "black", "lw": 0.5}
            ax.bar(x, vals, width, yerr=errs, capsize=3, label=f"{lms}: {fit.label}", **look)
        ax.set_xticks(np.arange(4), [entry_math(key) for key in keys])
        ax.set_ylabel(f"{MATRIX_NAMES[m]}  [{unit}]")
        ax.set_title(f"{MATRIX_NAMES[m]} from each load measuring system")
        ax.axhline(0, color="gray", lw=0.8)
        light_grid(ax, "y")
