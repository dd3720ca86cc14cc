"""The coherence of one operating point as a coloured table (the paper's Table 1).

Rows: orbit frequencies (forward whirl, then backward, ascending Omega/omega); columns:
the four motion/force pairs of each load measuring system; each cell shows gamma^2
with three decimals on the colour of its band (:data:`BANDS`), which the HTML page uses too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from matplotlib.colors import BoundaryNorm, ListedColormap
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from orbitrig.analysis import plots_narrow as narrow
from orbitrig.analysis.plots import style
from orbitrig.analysis.plot_panels import figure_legend, panels
from orbitrig.analysis.plot_marks import whirl_direction
from orbitrig.analysis.typeset import PAIRS, pair_math
from orbitrig.load_systems import LoadSystem

#: (lower bound, colour, label) of each gamma^2 band, best first
BANDS = (
    (0.99, "#1a9850", "\u2265 0.99"),
    (0.95, "#a6d96a", "0.95 \u2013 0.99"),
    (0.90, "#fee08b", "0.90 \u2013 0.95"),
    (0.0, "#f46d43", "< 0.90"),
)


def band_colour(gamma2: float) -> str:
    """Colour of the band gamma2 falls in, judged on the three decimals shown (NaN: grey)."""
    if not np.isfinite(gamma2):
        return "#cccccc"
    return next(colour for low, colour, _ in BANDS if round(float(gamma2), 3) >= low)


@dataclass(frozen=True)
class CoherenceTable:
    """gamma^2 in table order: ``values`` (rows, 4 * len(lms)), row labels and column labels."""

    values: np.ndarray
    rows: list[str]  # "0.200 fwd"
    columns: list[str]  # "piezo\nx, F$_\\mathrm{x}$"
    lms: list[LoadSystem]


def coherence_table(tables: dict) -> CoherenceTable | None:
    """The table of every load measuring system whose orbit table has gamma^2 and the same
    frequencies as the first one; None when no table has gamma^2."""
    have = {lms: t for lms, t in tables.items() if t.gamma2 is not None}
    if not have:
        return None
    ref = next(iter(have.values()))
    have = {lms: t for lms, t in have.items() if np.array_equal(t.orbit, ref.orbit)}
    ratio = ref.orbit / ref.spin
    dirs = whirl_direction(ref)
    order = np.lexsort((ratio, -dirs))
    values = np.hstack([np.asarray(t.gamma2, dtype=float)[order] for t in have.values()])
    rows = [f"{ratio[i]:.3f} {'fwd' if dirs[i] > 0 else 'bwd'}" for i in order]
    columns = [f"{lms}\n{label}" for lms in have for label in map(pair_math, PAIRS)]
    return CoherenceTable(values, rows, columns, list(have))


def coherence_figure(table: CoherenceTable, *, title: str) -> Figure:
    """The coloured table: one cell per (frequency, pair), gamma^2 written in the cell."""
    n_rows, n_cols = table.values.shape
    fig, axes = panels(1.05 * n_cols + 2.2, 0.4 * n_rows + 2.3, 1, 1, left=1.7, right=0.2, top=1.3, bottom=0.85)
    ax = axes[0, 0]
    bounds = [0.0] + [low for low, _, _ in reversed(BANDS[:-1])] + [1.0 + 1e-9]
    cmap = ListedColormap([colour for _, colour, _ in reversed(BANDS)])
    shown = np.round(np.nan_to_num(table.values, nan=0.0), 3)  # coloured as the number reads
    edges_x, edges_y = np.arange(n_cols + 1) - 0.5, np.arange(n_rows + 1) - 0.5
    ax.pcolormesh(edges_x, edges_y, shown, cmap=cmap, norm=BoundaryNorm(bounds, cmap.N))
    ax.set_xlim(-0.5, n_cols - 0.5)
    ax.set_ylim(n_rows - 0.5, -0.5)  # first row on top, as a table reads
    for (r, c), v in np.ndenumerate(table.values):
        ax.text(c, r, "-" if not np.isfinite(v) else f"{v:.3f}", ha="center", va="center", fontsize=style().small)
    ax.set_xticks(range(n_cols), table.columns, fontsize=style().small)
    ax.xaxis.tick_top()
    if narrow.is_narrow(style().width):  # the columns' names, set larger for their subscripts, stand upright
        ax.tick_params(axis="x", labelrotation=90)
    ax.set_yticks(range(n_rows), table.rows, fontsize=style().small)
    ax.set_ylabel("\u03a9/\u03c9  [-], whirl direction")
    for k in range(1, len(table.lms)):
        ax.axvline(4 * k - 0.5, color="black", lw=2)
    for r in range(1, n_rows):  # forward | backward
        if table.rows[r].split()[1] != table.rows[r - 1].split()[1]:
            ax.axhline(r - 0.5, color="black", lw=2)
    ax.tick_params(length=0)
    low = np.nanmin(table.values) if np.isfinite(table.values).any() else float("nan")
    handles = [Patch(color=colour, label=label) for _, colour, label in BANDS]
    figure_legend(
        fig,
        handles,
        [h.get_label() for h in handles],
        ncols=4,
        title=f"coherence \u03b3\u00b2 between displacement and force (lowest {low:.3f})",
    )
    fig.suptitle(title)
    return fig
