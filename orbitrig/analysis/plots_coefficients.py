"""The paper's Figures 6 and 7: K, C (and D) entries against Omega/omega (Agg, no pyplot).

A frequency-dependent identification is a curve from ``matrices(Omega)`` with a band of the
expanded uncertainty U = k u (k: plots.entry_k, each coefficient's own on a combined u, as
the table's, else the style's, 2 by default) and error bars at the tested
frequencies; a constant one is a horizontal line with its band. Curves are solid over the
tested orbit range and dotted outside it (extrapolation). u is sqrt(g^T Sigma g) with g the
entry's gradient in the free coefficients and Sigma the fit's covariance (exact for
correlated order terms): combined (statistical and calibration, as the tables' U) where the
run stored a budget (``Fitted.covariance``), else statistical; the legend says which. In simulator runs the truth is drawn as crosses at the tested
frequencies, always inside the axes: each fit's own truth (the true Z projected onto its
model, as the report's table beside the figure gives it; ``Fitted.truth``) in the fit's
colour; where no fit carries one, black crosses of the point's truth, its per-row K, C, D
where stored, else the constant best fit of the true impedance (K0, C0, D0), labelled so.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from orbitrig.analysis.grid import light_grid
from orbitrig.analysis.plots import ENTRIES, TRUTH_LABEL, Fitted, save_figure, entry_k, style
from orbitrig.analysis.typeset import entry_math
from orbitrig.analysis.plot_panels import figure_legend, panels
from orbitrig.analysis.plot_marks import (
    series_colors,
    keep_min_span,
    band,
    error_bars,
    keep_inside,
    marks_along,
    plot_fit,
    plot_line,
    series_look,
    split_tested,
    truth_look,
)
from rigunits import DISPLAY_UNITS, HZ
from reduction.derived import entry_gradient

#: the legend entry of the crosses of each fit's own truth (drawn in the fit's colour)
OWN_TRUTH_LABEL = "true (simulator) for the fit of this colour: true Z projected onto its model"
#: the legend entry of the point's truth when no fit carries its own
POINT_TRUTH_LABEL = TRUTH_LABEL + ": the constant K, C, D best fitting the true Z, or its per-row K, C, D"
#: points of each fitted curve over 0..1.05 max |Omega| (a panel is about 1.5 in wide: 60 points an inch)
CURVE_POINTS = 100


def entry_std(ident, matrix: str, entry: str, orbit: np.ndarray, covariance: np.ndarray | None = None) -> np.ndarray:
    """One standard uncertainty of matrix entry (e.g. "K", "xy") at each Omega (rad/s), SI, on
    ``covariance`` (the fit's own when None); zeros when there is none."""
    cov = ident.covariance if covariance is None else covariance
    if cov is None:
        return np.zeros(np.shape(orbit))
    g = entry_gradient(ident, matrix, entry, orbit)
    return np.sqrt(np.clip(np.einsum("kp,pq,kq->k", g, cov, g), 0, None))


def constant_std(fit: Fitted, matrix: str, entry: str) -> float:
    """The standard uncertainty of a fit's constant matrix entry (e.g. "K", "xy") on its band
    covariance (combined where the run stored a budget), SI; 0 for an entry the fit lacks."""
    if f"{matrix}{entry}" not in fit.identification.coefficients:
        return 0.0
    return float(entry_std(fit.identification, matrix, entry, np.zeros(1), fit.covariance)[0])


def _has(ident, matrix: str) -> bool:
    return any(k.startswith(matrix) for k in ident.coefficients)


def _draw_fit(axes, mats, fit: Fitted, n: int, color, grid, tested, spin, largest) -> None:
    """The n-th fit's curves, bands and error bars (its marker: plot_marks.series_look)."""
    ident = fit.identification
    on_grid = np.array([ident.matrices(w) for w in grid])  # (n, 3, 2, 2)
    at_tested = np.array([ident.matrices(w) for w in tested])
    constant = all("_" not in key for key in ident.coefficients)
    _, inside, _ = split_tested(grid, tested.min(), tested.max())
    # the fit's marker: on its error bars at the tested frequencies, else along its line
    marks = marks_along(n) if constant else {**series_look(n), "ms": 2.5, "markevery": []}
    for row, m in enumerate(mats):
        if not _has(ident, m):
            continue
        _, scale = DISPLAY_UNITS[m]
        mi = "KCD".index(m)
        for col, e in enumerate(ENTRIES):
            ax = axes[row, col]
            i, j = divmod(col, 2)
            val = on_grid[:, mi, i, j] * scale
            largest[m] = max(largest[m], float(np.max(np.abs(val))))
            k = entry_k(fit, m, e)
            bands = k * entry_std(ident, m, e, grid[inside], fit.covariance) * scale
            lo, hi = tested.min() / spin, tested.max() / spin
            plot_fit(ax, grid / spin, val, lo, hi, color=color, label=fit.label, marks=marks)
            band(ax, grid[inside] / spin, val[inside] - bands, val[inside] + bands, color=color)
            if not constant:
                err = k * entry_std(ident, m, e, tested, fit.covariance) * scale
                error_bars(
                    ax,
                    tested / spin,
                    at_tested[:, mi, i, j] * scale,
                    err,
                    color=color,
                    ms=2.5,
                    capsize=1.5,
                    lw=0.8,
                    look=series_look(n),
                )


def own_truth_matrices(fit: Fitted, orbit: np.ndarray) -> np.ndarray | None:
    """(n, 3, 2, 2) K, C, D of the fit's own truth (``fit.truth``, keyed as its coefficients)
    at each |Omega| (rad/s) in `orbit`, SI; NaN where the truth lacks a term; None without one."""
    if not fit.truth:
        return None
    out = np.zeros((len(orbit), 3, 2, 2))
    for term in fit.identification.spec.terms:
        value = fit.truth.get(term.name)
        for i, j in term.entries:
            out[:, "KCD".index(term.matrix), i, j] += (np.nan if value is None else value) * orbit**term.order
    return out


def _draw_own_truth(axes, mats, fit: Fitted, color, tested, spin, largest) -> None:
    mat = own_truth_matrices(fit, tested)
    if mat is None:
        return
    for row, m in enumerate(mats):
        if not _has(fit.identification, m):
            continue
        _, scale = DISPLAY_UNITS[m]
        values = mat[:, "KCD".index(m)] * scale
        if np.isfinite(values).any():
            largest[m] = max(largest[m], float(np.nanmax(np.abs(values))))
        for col in range(4):
            i, j = divmod(col, 2)
            plot_line(
                axes[row, col], tested / spin, values[:, i, j], label=OWN_TRUTH_LABEL, **truth_look("small", color)
            )


def truth_matrix(truth: dict, matrix: str) -> tuple[np.ndarray, np.ndarray] | None:
    """(|Omega| (n,) rad/s, true entries (n, 2, 2) SI) of `matrix` ('K', 'C', 'D') at the truth's
    rows: its per-row values when stored, else its constant best fit (``K0``...) at every row;
    None when the truth has neither."""
    orbit = truth.get("orbit")
    if orbit is None and truth.get("orbit_hz") is not None:
        orbit = HZ * np.asarray(truth["orbit_hz"], dtype=float)
    if orbit is None or len(orbit) == 0:
        return None
    w = np.abs(np.asarray(orbit, dtype=float))
    per_row = truth.get(matrix)
    if per_row is not None and np.shape(per_row) == (len(w), 2, 2):
        return w, np.asarray(per_row, dtype=float)
    const = truth.get(f"{matrix}0")
    if const is None:
        return None
    return w, np.broadcast_to(np.asarray(const, dtype=float), (len(w), 2, 2))


def _draw_truth(axes, mats, truth: dict, spin: float, largest) -> None:
    for row, m in enumerate(mats):
        found = truth_matrix(truth, m)
        if found is None:
            continue
        t_orbit, mat = found
        _, scale = DISPLAY_UNITS[m]
        largest[m] = max(largest[m], float(np.max(np.abs(mat))) * scale)
        for col in range(4):
            i, j = divmod(col, 2)
            plot_line(
                axes[row, col], t_orbit / spin, mat[:, i, j] * scale, label=POINT_TRUTH_LABEL, **truth_look("small")
            )


def coefficients_figure(
    fitted: Sequence[Fitted], *, spin: float, orbit: np.ndarray, truth: dict | None, title: str
) -> Figure:
    """K, C, D entries of every identification in `fitted` against Omega/omega (one model)."""
    mats = [m for m in "KCD" if any(_has(f.identification, m) for f in fitted)]
    # wspace: room for a y label beside tick labels as wide as "−500" (D in kg) clear of the panel to its left
    fig, axes = panels(13, 2.7 * len(mats) + 2.0, len(mats), 4, bottom=1.35, hspace=0.35, wspace=0.6)
    top = float(np.max(np.abs(orbit))) * 1.05
    tested = np.unique(np.round(np.abs(orbit), 9))
    grid = np.union1d(np.linspace(0.0, top, CURVE_POINTS), tested[[0, -1]])  # the solid part ends on the tested range
    largest = dict.fromkeys(mats, 0.0)  # largest |entry| drawn per matrix, display units
    for n, (fit, color) in enumerate(zip(fitted, series_colors(len(fitted)))):
        _draw_fit(axes, mats, fit, n, color, grid, tested, spin, largest)
        _draw_own_truth(axes, mats, fit, color, tested, spin, largest)
    if truth and not any(f.truth for f in fitted):  # else each fit's own truth, as the table gives it
        _draw_truth(axes, mats, truth, spin, largest)
    axes[0, 0].set_xlim(0, top / spin)  # shared by every panel
    for row, m in enumerate(mats):
        unit, _ = DISPLAY_UNITS[m]
        for col, e in enumerate(ENTRIES):
            ax = axes[row, col]
            ax.set_title(entry_math(m + e))
            ax.set_ylabel(f"{entry_math(m + e)}  [{unit}]")  # the entry with its unit, as the title names it
            light_grid(ax)
            keep_min_span(ax, largest[m])
            for line in ax.get_lines():  # the truth crosses, whatever limits were chosen
                if line.get_label() in (OWN_TRUTH_LABEL, POINT_TRUTH_LABEL):
                    keep_inside(ax, line.get_xdata(), line.get_ydata())
            if row == len(mats) - 1:
                ax.set_xlabel("\u03a9/\u03c9  [-]")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    uniq = dict(zip(labels, handles))
    figure_legend(
        fig,
        list(uniq.values()),
        list(uniq.keys()),
        ncols=min(3, len(uniq)),
        title=style().band_label(bases=[f.basis for f in fitted]) + "; solid over the tested range, dotted beyond",
        fit=True,  # the figure's height fitted to the legend: no empty band above it
    )
    fig.suptitle(title)
    return fig


def coefficients_plot(
    path, fitted: Sequence[Fitted], *, spin: float, orbit: np.ndarray, truth: dict | None, title: str
) -> Path:
    """:func:`coefficients_figure` written to `path` (PNG)."""
    return save_figure(coefficients_figure(fitted, spin=spin, orbit=orbit, truth=truth, title=title), path)
