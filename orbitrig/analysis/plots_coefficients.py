"""The paper's Figures 6 and 7: K, C (and D) entries against Omega/omega (Agg, no pyplot).

A frequency-dependent identification is a curve from ``matrices(Omega)`` with a band of one
standard uncertainty and error bars at the tested frequencies; a constant one is a horizontal
line with its band. The band is sqrt(g^T Sigma g) with g the entry's gradient in the free
coefficients and Sigma the fit's covariance (exact for correlated order terms). The
simulator's true values are black crosses, always inside the axes.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from orbitrig.analysis.plots import ENTRIES, TRUTH_LABEL, Fitted, _colors, _min_span, _save, keep_inside, panel_figure
from orbitrig.analysis.reduce import MATRIX_UNITS
from reduction.derived import entry_gradient


def entry_std(ident, matrix: str, entry: str, orbit: np.ndarray) -> np.ndarray:
    """One standard uncertainty of matrix entry (e.g. "K", "xy") at each Omega (rad/s), SI;
    zeros when the fit has no covariance."""
    if ident.covariance is None:
        return np.zeros(np.shape(orbit))
    g = entry_gradient(ident, matrix, entry, orbit)
    return np.sqrt(np.clip(np.einsum("kp,pq,kq->k", g, ident.covariance, g), 0, None))


def _has(ident, matrix: str) -> bool:
    return any(k.startswith(matrix) for k in ident.coefficients)


def _draw_fit(axes, mats, fit: Fitted, color, grid, tested, spin, largest) -> None:
    ident = fit.identification
    on_grid = np.array([ident.matrices(w) for w in grid])  # (n, 3, 2, 2)
    at_tested = np.array([ident.matrices(w) for w in tested])
    constant = all("_" not in key for key in ident.coefficients)
    for row, m in enumerate(mats):
        if not _has(ident, m):
            continue
        _, scale = MATRIX_UNITS[m]
        mi = "KCD".index(m)
        for col, e in enumerate(ENTRIES):
            ax = axes[row, col]
            i, j = divmod(col, 2)
            val = on_grid[:, mi, i, j] * scale
            largest[m] = max(largest[m], float(np.max(np.abs(val))))
            band = entry_std(ident, m, e, grid) * scale
            ax.plot(grid / spin, val, color=color, lw=1.6, label=fit.label)
            ax.fill_between(grid / spin, val - band, val + band, color=color, alpha=0.15, lw=0)
            if not constant:
                ax.errorbar(tested / spin, at_tested[:, mi, i, j] * scale,
                            yerr=entry_std(ident, m, e, tested) * scale,
                            fmt="o", ms=3.5, color=color, capsize=2.5, lw=1)  # fmt: skip


def _draw_truth(axes, mats, truth: dict, spin: float, largest) -> None:
    t_orbit = 2 * np.pi * np.abs(np.asarray(truth.get("orbit_hz", []), dtype=float))
    for row, m in enumerate(mats):
        mat = truth.get(m)
        if mat is None or len(t_orbit) == 0:
            continue
        mat = np.asarray(mat, dtype=float)
        _, scale = MATRIX_UNITS[m]
        largest[m] = max(largest[m], float(np.max(np.abs(mat))) * scale)
        for col in range(4):
            i, j = divmod(col, 2)
            axes[row, col].plot(t_orbit / spin, mat[:, i, j] * scale, "x", color="black", ms=6,
                                mew=1.5, label=TRUTH_LABEL, zorder=6)  # fmt: skip


def coefficients_figure(fitted: Sequence[Fitted], *, spin: float, orbit: np.ndarray, truth: dict | None,
                        title: str) -> Figure:  # fmt: skip
    """K, C, D entries of every identification in `fitted` against Omega/omega (one model)."""
    mats = [m for m in "KCD" if any(_has(f.identification, m) for f in fitted)]
    fig = panel_figure(13, 2.7 * len(mats) + 2.0, bottom=1.35, hspace=0.35)
    axes = np.atleast_2d(fig.subplots(len(mats), 4, sharex=True))
    top = float(np.max(np.abs(orbit))) * 1.05
    grid = np.linspace(0.0, top, 200)
    tested = np.unique(np.round(np.abs(orbit), 9))
    largest = dict.fromkeys(mats, 0.0)  # largest |entry| drawn per matrix, display units
    for fit, color in zip(fitted, _colors(len(fitted))):
        _draw_fit(axes, mats, fit, color, grid, tested, spin, largest)
    if truth:
        _draw_truth(axes, mats, truth, spin, largest)
    for row, m in enumerate(mats):
        unit, _ = MATRIX_UNITS[m]
        for col, e in enumerate(ENTRIES):
            ax = axes[row, col]
            ax.set_title(f"{m}{e}")
            ax.set_ylabel(f"{m}{e}  [{unit}]")
            ax.grid(True, alpha=0.3)
            ax.set_xlim(0, top / spin)
            _min_span(ax, largest[m])
            for line in ax.get_lines():  # the truth crosses, whatever limits were chosen
                if line.get_label() == TRUTH_LABEL:
                    keep_inside(ax, line.get_xdata(), line.get_ydata())
            if row == len(mats) - 1:
                ax.set_xlabel("\u03a9/\u03c9  [-]")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    uniq = dict(zip(labels, handles))
    fig.legend(list(uniq.values()), list(uniq.keys()), loc="lower center", ncols=min(5, len(uniq)),
               fontsize=9, title="bands and error bars: \u00b11 standard uncertainty (statistical)")  # fmt: skip
    fig.suptitle(title)
    return fig


def coefficients_plot(path, fitted: Sequence[Fitted], *, spin: float, orbit: np.ndarray, truth: dict | None,
                      title: str) -> Path:  # fmt: skip
    """:func:`coefficients_figure` written to `path` (PNG)."""
    return _save(coefficients_figure(fitted, spin=spin, orbit=orbit, truth=truth, title=title), path)
