"""Figures of the stored signals (matplotlib Agg, no pyplot state).

- :func:`signals_figure`: the paper's Figure 4 for one orbit frequency: (a) F_x and (b) F_y
  time-averaged over the averaged revolutions from both load measuring systems, with their
  amplitude and phase difference; (c) F_x and (d) F_y of one raw revolution against the
  average; each panel a letter of its own, one legend under the panels.
- :func:`orbits_figure`: the measured x-y orbit of both probe planes, one panel per
  orbit frequency (the rig engineer's first sanity check): plane A solid, B dash-dotted.

Each ``*_figure`` returns the Figure (tests read back what was drawn); ``save`` writes it.
Forces are on the journal (N), displacements in um, orbit angle in deg after the trigger.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from matplotlib.figure import Figure

from orbitrig.analysis import plots_narrow as narrow
from orbitrig.analysis.plots import DATA_ROOM, style
from orbitrig.analysis.grid import light_grid
from orbitrig.analysis.plot_panels import figure_legend, max_columns, panels
from orbitrig.analysis.plot_marks import series_colors, plot_line
from orbitrig.analysis.rounding import at_decimals, orbit_frequency
from orbitrig.analysis.typeset import force_math
from orbitrig.analysis.signals import FORCE_CHANNELS, PROBE_PLANES, BlockSignals
from orbitrig.load_systems import DIFFERENCE, DIFFERENCE_WORDS, LMS, LoadSystem, relative_difference
from reduction.fourier import harmonic_fit
from reduction.whirl import Whirl
from rigunits import MICROMETRE, UM

#: the line of probe planes A and B in an orbit panel (a greyscale print tells them apart; the
#: commanded radius is thin, grey and dashed)
PLANE_LINES = ("-", "-.")


@dataclass(frozen=True)
class LmsDifference:
    """Piezoelectric minus strain-gauge force relative to piezoelectric (load_systems.DIFFERENCE,
    as the page's consistency table), from the averaged signals' fundamentals."""

    amplitude_pct: float  # (|F_piezo| - |F_strain|) / |F_piezo|, percent
    phase_deg: float  # phase(F_piezo) - phase(F_strain), deg in (-180, 180]


def fundamental(theta: np.ndarray, values: np.ndarray):
    """HarmonicFit (dc, phasor, rms_residual) of one channel's samples at angles theta (rad)."""
    return harmonic_fit(values, theta)


def lms_difference(sig: BlockSignals, axis: str) -> LmsDifference:
    """Piezo minus strain of force `axis` ('fx' | 'fy') from the block's averaged waveforms."""
    q = {}
    for lms in LMS:
        i = sig.channels[f"{axis}_{lms}"]
        q[lms] = complex(fundamental(sig.theta[i], sig.mean[i]).phasor)
    amplitude, phase = relative_difference(*(q[lms] for lms in DIFFERENCE))
    return LmsDifference(100.0 * float(amplitude), math.degrees(float(phase)))


def plane_orbit(sig: BlockSignals, x_name: str, y_name: str) -> tuple[np.ndarray, np.ndarray]:
    """Averaged (x, y) of one probe plane at the x channel's angles (ascending); y, sampled at
    its own slots, is interpolated (periodic) to those angles. m."""
    deg_x, x, _ = sig.of(x_name)
    deg_y, y, _ = sig.of(y_name)
    return x, np.interp(deg_x, deg_y, y, period=360.0)


def _direction(sig: BlockSignals) -> str:
    return Whirl.of(sig.frequency.direction)


def signals_figure(sig: BlockSignals, *, title: str) -> Figure:
    """Figure 4 of the paper for one block: the first row both systems' averaged F_x (a) and F_y
    (b), the amplitude and phase difference in each panel's title; the second one raw revolution
    of the piezoelectric F_x (c) and F_y (d) against their average, with the RMS deviation from
    the fundamental. The y labels name the force (typeset, F$_\\mathrm{x}$  [N]: short, as a subscript
    sets the axis labels larger); the titles, a long second line each, are set at the smallest text
    size (a subscript would set them larger, wider than a panel)."""
    fig, axes = panels(12, 8.0, 2, 2, left=0.9, right=0.35, top=1.35, bottom=1.05, hspace=0.36, wspace=0.22)
    colors = series_colors(2)
    for col, axis in enumerate(("fx", "fy")):
        label = force_math(axis[1])
        ax = axes[0, col]
        for k, lms in enumerate(LMS):
            deg, mean, _ = sig.of(FORCE_CHANNELS[lms][col])
            ax.plot(deg, mean, "-", color=colors[k], lw=2.4 - 1.2 * k, label=f"{lms}")
        d = lms_difference(sig, axis)
        ax.set_title(_average_title("ab"[col], sig.n_revolutions, d), fontsize=style().small)
        ax.set_ylabel(f"{label}  [N]")
        ax = axes[1, col]
        name = FORCE_CHANNELS[LoadSystem.PIEZO][col]
        deg, mean, raw = sig.of(name)
        i = sig.channels[name]
        rms_raw = float(fundamental(sig.theta[i], sig.raw[i]).rms_residual)
        rms_mean = float(fundamental(sig.theta[i], sig.mean[i]).rms_residual)
        ax.plot(deg, raw, ".-", color="0.5", lw=0.8, ms=3.5, label=f"revolution {sig.revolution + 1} (raw)")
        ax.plot(deg, mean, "-", color=colors[0], lw=2.4, label=f"average of {sig.n_revolutions}")
        ax.set_title(_raw_title("cd"[col], rms_raw, rms_mean), fontsize=style().small)
        ax.set_ylabel(f"{label}  [N]")
        ax.set_xlabel("orbit angle after the trigger  [deg]")
    for ax in axes.flat:
        ax.set_xlim(0, 360)
        ax.set_xticks(range(0, 361, 45 if max_columns(4) == 4 else 90))
        light_grid(ax)
    _signals_legend(fig, axes, sig)
    fig.suptitle(title)
    return fig


def _average_title(letter: str, n: int, d: LmsDifference) -> str:
    """Panel (a) or (b): both systems' averages and their difference; in a narrow figure without
    the systems and revolutions the legend's entries give (three lines at most, not five)."""
    amplitude, phase = f"{d.amplitude_pct:+.2f} % of |{DIFFERENCE[0]}|", f"phase {d.phase_deg:+.2f} deg"
    if narrow.is_narrow(style().width):
        return f"({letter}) {DIFFERENCE_WORDS}:\n{amplitude}, {phase}"
    return f"({letter}) both systems, average of {n} revolutions\n{DIFFERENCE_WORDS}: {amplitude}, {phase}"


def _raw_title(letter: str, rms_raw: float, rms_mean: float) -> str:
    """Panel (c) or (d): the piezo's RMS deviations from the fundamental, the unit once (what the
    legend's entries give, one revolution and the average, left to it: two lines within the panel
    at 175 mm); in a narrow figure without the system too (three lines at most, not five)."""
    if narrow.is_narrow(style().width):
        return f"({letter}) RMS deviation from the fundamental: raw {rms_raw:.3g}, average {rms_mean:.3g} N"
    return f"({letter}) piezo, RMS deviation from the fundamental:\nraw {rms_raw:.3g}, average {rms_mean:.3g} N"


def _signals_legend(fig: Figure, axes, sig: BlockSignals) -> None:
    """One legend under the panels (none in a panel covers data): both systems' averages of the
    first row (piezo's is the second row's average too) and the second row's raw revolution."""
    (piezo, strain), (raw, _) = axes[0, 0].get_lines(), axes[1, 0].get_lines()
    n = sig.n_revolutions
    labels = [f"piezo, average of {n}", f"strain, average of {n}", f"piezo, {raw.get_label()}"]
    figure_legend(fig, [piezo, strain, raw], labels, ncols=3, frameon=False)


def orbits_figure(blocks: Sequence[BlockSignals], *, radius: float, title: str) -> Figure:
    """x-y orbit (averaged displacements) of probe planes A and B, one panel per block, in um,
    equal axes; the commanded orbit radius (m) as a dashed circle about the measured centre, and
    each plane's mean radius (mean distance from its centre) in the panel title."""
    n = len(blocks)
    cols = min(max_columns(5), max(1, n))
    rows = max(1, math.ceil(n / cols))
    width, height = 2.7 * cols + 0.8, 3.4 * rows + 1.6
    margins = {"left": 0.7, "right": 0.45, "top": 1.25, "bottom": 1.0, "wspace": 0.45, "hspace": 0.9}
    fig, grid = panels(width, height, rows, cols, sharex=False, **margins)
    axes = grid.ravel()
    for ax, sig in zip(axes, blocks):
        _orbit_panel(ax, sig, radius)
    for ax in axes[n:]:
        ax.set_visible(False)
    for ax in axes[(rows - 1) * cols : (rows - 1) * cols + cols]:
        ax.set_xlabel(f"x  [{MICROMETRE}]", fontsize=style().small)
    for ax in axes[::cols]:
        ax.set_ylabel(f"y  [{MICROMETRE}]", fontsize=style().small)
    handles, labels = axes[0].get_legend_handles_labels()
    figure_legend(fig, handles, labels, ncols=len(labels), frameon=False)
    fig.suptitle(title)
    return fig


def _radii_text(radii: list[float]) -> list[str]:
    """The planes' mean radii (m) in µm to one decimal, the larger's third significant digit
    (2.38 and 2.40, not 2.38 and 2.4)."""
    largest = max((abs(r) for r in radii if math.isfinite(r) and r != 0), default=UM)
    return [at_decimals(r / UM, 2 - math.floor(math.log10(largest / UM))) for r in radii]


def _orbit_panel(ax, sig: BlockSignals, radius: float) -> None:
    """Both probe planes' orbits of one block, the trigger and the sense of the motion, the
    commanded radius (m) about the measured centre and each plane's mean radius in the title."""
    colors = series_colors(2)
    circle = np.linspace(0, 2 * np.pi, 121)
    centre, radii = [], []
    for k, (plane, (xn, yn)) in enumerate(PROBE_PLANES.items()):
        x, y = plane_orbit(sig, xn, yn)
        line = {"ls": PLANE_LINES[k], "color": colors[k], "lw": 1.4, "label": f"plane {plane}"}
        plot_line(ax, np.append(x, x[0]) / UM, np.append(y, y[0]) / UM, **line)
        if k == 0:  # the trigger (0 deg) and the sense of the motion
            ax.plot(x[0] / UM, y[0] / UM, "o", color="black", ms=4, label="trigger (0 deg)")
            j = max(1, len(x) // 12)
            arrow = {"arrowstyle": "->", "color": "black", "lw": 1.2}
            ax.annotate("", xy=(x[j] / UM, y[j] / UM), xytext=(x[0] / UM, y[0] / UM), arrowprops=arrow)
        centre.append((x.mean(), y.mean()))
        radii.append(float(np.mean(np.hypot(x - x.mean(), y - y.mean()))))
    cx, cy = np.mean(centre, axis=0)
    if math.isfinite(radius) and radius > 0:
        xs, ys = (cx + radius * np.cos(circle)) / UM, (cy + radius * np.sin(circle)) / UM
        plot_line(ax, xs, ys, "--", color="0.4", lw=0.8, label="commanded radius")
    f = sig.frequency
    a, b = _radii_text(radii)
    ax.set_title(
        f"{orbit_frequency(f.orbit_hz)} {_direction(sig)}\nmean radius\nA {a}, B {b} {MICROMETRE}",  # short lines: neighbours apart
        fontsize=style().small,
    )
    # equal axes fitted to the data limits (matplotlib: 2.5 % of room, margins ignored): the data
    # limits take DATA_ROOM on every side, in place of the margins
    (x0, y0), (x1, y1) = ax.dataLim.get_points()
    room = DATA_ROOM * max(x1 - x0, y1 - y0)
    ax.update_datalim([(x0 - room, y0 - room), (x1 + room, y1 + room)])
    ax.margins(0)
    ax.set_aspect("equal", adjustable="datalim")
    light_grid(ax)
    ax.tick_params(labelsize=style().small)
