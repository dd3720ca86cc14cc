"""Grid lines drawn as one artist per axes.

matplotlib's ``ax.grid`` draws each grid line as its own Line2D artist per tick (about a fifth
of a report figure's drawing time); :func:`light_grid` adds one artist that draws the grid
lines of the axes' major ticks as a single LineCollection, in the same colour, width and place
(between patches and lines); the collection is made once and given each draw's lines.
"""

from __future__ import annotations

import matplotlib as mpl
from matplotlib.artist import Artist
from matplotlib.collections import LineCollection

GRID_GID = "light-grid"


class _Grid(Artist):
    """The grid lines of the major ticks of `which` ('x', 'y' or 'both') of its axes."""

    def __init__(self, which: str, alpha: float):
        super().__init__()
        self.which = which
        self.set_alpha(alpha)
        self.set_gid(GRID_GID)
        self.set_zorder(1.5)  # where matplotlib puts grid lines (axes.axisbelow: 'line')
        self._lines: tuple[tuple, LineCollection] | None = None  # (what it was made for, the collection)

    def draw(self, renderer) -> None:
        ax = self.axes
        fig = ax.get_figure(root=False) if ax is not None else None
        if ax is None or fig is None or not self.get_visible():
            return
        (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
        segments = []
        if self.which in ("x", "both"):
            segments += [[(x, y0), (x, y1)] for x in ax.xaxis.get_majorticklocs() if min(x0, x1) <= x <= max(x0, x1)]
        if self.which in ("y", "both"):
            segments += [[(x0, y), (x1, y)] for y in ax.yaxis.get_majorticklocs() if min(y0, y1) <= y <= max(y0, y1)]
        if not segments:
            return
        rc = mpl.rcParams
        look = (
            rc["grid.color"],
            rc["grid.linewidth"],
            rc["grid.linestyle"],
            self.get_alpha(),
            ax.transData,
            ax.bbox,
            fig,
        )
        if self._lines is None or self._lines[0] != look:  # made once, for every later draw alike
            lines = LineCollection([], colors=look[0], linewidths=look[1], linestyles=look[2], alpha=look[3])
            lines.set_transform(ax.transData)
            lines.set_figure(fig)
            lines.set_clip_box(ax.bbox)
            self._lines = look, lines
        self._lines[1].set_segments(segments)
        self._lines[1].draw(renderer)


def light_grid(ax, which: str = "both", alpha: float = 0.3) -> None:
    """Grid lines on `ax` at its major ticks, as ``ax.grid(True, axis=which, alpha=alpha)``
    draws them; once per axes (a reused figure keeps it)."""
    if not any(a.get_gid() == GRID_GID for a in ax.artists):
        ax.add_artist(_Grid(which, alpha))
