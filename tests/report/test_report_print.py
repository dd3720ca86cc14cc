"""Every figure kind reads as printed, in greyscale, at both journal widths (renderer extents,
as drawn into the PNG): every legend lies inside the figure and covers no data (a legend in a
panel holds none of its data points, a legend under the panels none of them), and the entries
of every legend differ in more than colour (line style, width, marker and its fill; a filled
patch's hatch or grey level: what a greyscale print keeps), no glyph prints smaller than 7 pt
(a subscript's neither: each glyph measured as mathtext lays it out), every labelled x axis
shows the values of its ticks, the fits of the forces' residual panels differ in more than
line width, and no text shows a raw underscore, caret, a Greek letter spelled out in ASCII or
a coefficient's name unsubscripted (Kxx; subscripts and symbols drawn as the paper writes
them: mathtext, Unicode), no text is wrapped between a value and its unit or after a condition's
``=``, and no panel's tick labels or y label come within PANEL_CLEARANCE of the panel on its left."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from matplotlib.collections import Collection, QuadMesh
from matplotlib.colors import to_rgba
from matplotlib.lines import Line2D
from matplotlib.offsetbox import DrawingArea, OffsetBox, TextArea
from matplotlib.patches import Patch

from orbitrig.analysis import plots
from support.report_figures import (
    ASCII_STAND_INS,
    KINDS,
    checks,
    figure_texts,
    plain_entries,
    split_values,
    printed_pt,
    shown,
)

#: the smallest text a journal prints (pt)
SMALLEST_PT = 7.0


def _data_points(ax) -> np.ndarray:
    """(n, 2) display coordinates of the data `ax` draws inside its box: line vertices and
    markers, vertices of collections (bands, error bars) and corners of patches (bars)."""
    parts = [
        line.get_xydata() for line in ax.get_lines() if line.get_visible() and line.get_transform() == ax.transData
    ]
    for c in ax.collections:
        if c.get_visible() and c.get_transform() == ax.transData:
            parts += [p.vertices for p in c.get_paths()]
    for p in ax.patches:
        if p.get_visible() and p.get_transform().contains_branch(ax.transData):
            parts.append(ax.transData.inverted().transform(p.get_verts()))
    pts = ax.transData.transform(np.concatenate(parts)) if parts else np.zeros((0, 2))
    box = ax.bbox
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    inside = (pts[:, 0] >= box.x0) & (pts[:, 0] <= box.x1) & (pts[:, 1] >= box.y0) & (pts[:, 1] <= box.y1)
    return pts[inside]


def _legends_over_data(fig) -> list[str]:
    """Legends (by their first entry) holding data points of a panel, with how many, or reaching
    past the figure's edge."""
    renderer = fig.canvas.get_renderer()
    legends = [*fig.legends, *(ax.get_legend() for ax in fig.axes if ax.get_visible())]
    out = []
    for legend in (lg for lg in legends if lg is not None and lg.get_visible()):
        box = legend.get_window_extent(renderer)
        edge = fig.bbox
        if box.x0 < edge.x0 - 0.5 or box.x1 > edge.x1 + 0.5 or box.y0 < edge.y0 - 0.5 or box.y1 > edge.y1 + 0.5:
            out.append(f"legend {legend.get_texts()[0].get_text()!r} reaches past the figure: {box.bounds}")
        for ax in (a for a in fig.axes if a.get_visible()):
            pts = _data_points(ax)
            n = int(np.sum((pts[:, 0] > box.x0) & (pts[:, 0] < box.x1) & (pts[:, 1] > box.y0) & (pts[:, 1] < box.y1)))
            if n:
                first = legend.get_texts()[0].get_text() if legend.get_texts() else "?"
                out.append(f"legend {first!r} covers {n} data points of panel {ax.get_title()!r}")
    return out


def _grey(color) -> float:
    r, g, b, a = to_rgba(color)
    return round((0.299 * r + 0.587 * g + 0.114 * b) * a + (1 - a), 1)  # on white paper


def _look(artist) -> tuple:
    """What a greyscale print keeps of one artist of a legend entry: a line's style, width and
    marker (filled or open); a patch's hatch and grey level; a collection's line style, and grey
    level when filled."""
    if isinstance(artist, Line2D):
        marker = artist.get_marker() if artist.get_marker() not in (None, "None", "", " ") else None
        ls = artist.get_linestyle() if artist.get_linestyle() not in ("None", "", " ") else None
        open_marker = marker is not None and _grey(artist.get_markerfacecolor()) == 1.0
        return ("line", ls, round(artist.get_linewidth(), 1) if ls else None, marker, open_marker)
    if isinstance(artist, Patch):
        return ("patch", artist.get_hatch(), _grey(artist.get_facecolor()))
    if isinstance(artist, Collection):
        filled = len(artist.get_facecolor()) > 0
        return (
            "collection",
            tuple(artist.get_linestyle()[0][1] or ()),
            _grey(artist.get_facecolor()[0]) if filled else None,
        )
    return (type(artist).__name__,)


def _entries(legend) -> list[tuple[str, tuple]]:
    """(text, look of every artist its handle draws) of each entry of `legend`."""
    out = []

    def walk(box):
        kids = box.get_children()
        if len(kids) == 2 and isinstance(kids[0], DrawingArea) and isinstance(kids[1], TextArea):
            out.append((kids[1].get_text(), tuple(sorted(map(_look, kids[0].get_children()), key=repr))))
            return
        for kid in kids:
            if isinstance(kid, OffsetBox):
                walk(kid)

    walk(legend._legend_handle_box)
    return out


def _colour_only(fig) -> list[str]:
    """Pairs of entries of one legend that differ only in colour."""
    out = []
    legends = [*fig.legends, *(ax.get_legend() for ax in fig.axes if ax.get_visible())]
    for legend in (lg for lg in legends if lg is not None):
        for (la, a), (lb, b) in itertools.combinations(_entries(legend), 2):
            if a == b:
                out.append(f"{la!r} and {lb!r} differ only in colour: {a}")
    return out


def _residuals_told_by_width(fig) -> list[str]:
    """Pairs of fits' lines in a panel of residuals (the forces figure's) that a greyscale print
    tells apart by their width alone (same line style, marker and marker fill)."""
    out = []
    for ax in (a for a in fig.axes if a.get_visible() and "residual" in a.get_title()):
        lines = [line for line in ax.get_lines() if line.get_gid() != "measured-uncertainty"]
        for a, b in itertools.combinations(lines, 2):
            if _look(a)[1] == _look(b)[1] and _look(a)[3:] == _look(b)[3:]:
                out.append(f"panel {ax.get_title()!r}: two fits differ only in width and colour: {_look(a)}")
    return out


def _small_texts(fig) -> list[str]:
    """Texts whose smallest glyph (a subscript's among them) prints under SMALLEST_PT (the figure
    is drawn at its print size)."""
    sizes = {t: printed_pt(t) for t in figure_texts(fig)}
    return [f"{pt:.3g} pt: {t.get_text()!r}" for t, pt in sizes.items() if pt < SMALLEST_PT - 1e-9]


def _unnumbered_axes(fig) -> list[str]:
    """Labelled x axes of visible panels that show no tick label (a quantity without numbers); the
    figure as drawn (checked_figures draws it at its own dpi before checking it)."""
    return [
        f"x axis {ax.get_xlabel()!r} of panel {ax.get_title()!r} has no tick labels"
        for ax in fig.axes
        if ax.get_visible()
        and ax.get_xlabel()
        and not any(t.label1.get_visible() and t.label1.get_text() for t in ax.xaxis._update_ticks())
    ]


def _ascii_stand_ins(fig) -> list[str]:
    """Texts showing an ASCII stand-in for a subscript, power or Greek letter."""
    return [f"{t.get_text()!r}" for t in figure_texts(fig) if ASCII_STAND_INS.search(shown(t.get_text()))]


def _legend_over_panels(fig) -> list[str]:
    """Panels (by title) whose extent as drawn (tick labels, axis labels, title) a figure legend
    touches: its room was measured at the size it prints at."""
    renderer = fig.canvas.get_renderer()
    out = []
    for legend in fig.legends:
        box = legend.get_window_extent(renderer)
        covered = [ax for ax in fig.axes if ax.get_visible() and box.overlaps(ax.get_tightbbox(renderer))]
        out += [f"legend touches panel {ax.get_title()!r} ({ax.get_xlabel()!r})" for ax in covered]
    return out


def _broken_values(fig) -> list[str]:
    """Texts wrapped inside a value and its unit or a condition's ``symbol = value unit``."""
    return [p for t in figure_texts(fig) for p in split_values(t.get_text())]


#: the least room (pt) between a panel's tick labels and y label and the panel to its left
PANEL_CLEARANCE = 3.0


def _crowded_panels(fig) -> list[str]:
    """Panels (by y label) whose tick labels or y label come closer than PANEL_CLEARANCE to the
    frame of a panel beside them, on its left."""
    renderer = fig.canvas.get_renderer()
    axes = [ax for ax in fig.axes if ax.get_visible()]
    out = []
    for ax, left in itertools.permutations(axes, 2):
        box, frame = ax.get_tightbbox(renderer), left.bbox
        beside = frame.x1 <= ax.bbox.x0 and min(box.y1, frame.y1) > max(box.y0, frame.y0)
        gap = (box.x0 - frame.x1) * 72.0 / fig.dpi
        if beside and gap < PANEL_CLEARANCE:
            out.append(f"{ax.get_ylabel()!r} {gap:.2f} pt from the panel {left.get_title()!r} on its left")
    return out


#: the body text's size (pt): panel titles, axis labels, legend titles (the suptitle: 1.2 times it)
BODY_PT = plots.FigureStyle().font


def _enlarged_texts(fig) -> list[str]:
    """Texts set larger than the body text (the suptitle: larger than 1.2 times it): a text with
    subscripts keeps the size of the texts without (mathtext's subscripts at 0.7 of it had a
    panel title with one set at 8.6 pt, its subscripts' 6 pt, beside 6.5-pt titles)."""
    suptitle = fig._suptitle  # type: ignore[attr-defined]
    return [
        f"{t.get_fontsize():.3g} pt: {t.get_text()!r}"
        for t in figure_texts(fig)
        if t.get_fontsize() > (1.2 if t is suptitle else 1.0) * BODY_PT + 1e-9
    ]


def _unit_only_labels(fig) -> list[str]:
    """Axis labels of visible panels that give a unit without naming the quantity before it, in
    the labels' style ``quantity  [unit]`` (the derived figure's effective damping read ``[kN s/m]``)."""
    labels = [axis.label.get_text() for ax in fig.axes if ax.get_visible() for axis in (ax.xaxis, ax.yaxis)]
    return [f"a unit alone: {label!r}" for label in labels if label.strip().startswith("[")]


def _check(fig) -> list[str]:
    return (
        _legends_over_data(fig)
        + _legend_over_panels(fig)
        + _colour_only(fig)
        + _small_texts(fig)
        + _enlarged_texts(fig)
        + _unit_only_labels(fig)
        + _unnumbered_axes(fig)
        + _ascii_stand_ins(fig)
        + plain_entries(fig)
        + _residuals_told_by_width(fig)
        + _broken_values(fig)
        + _crowded_panels(fig)
    )


@pytest.mark.parametrize("width", sorted(plots.COLUMN_WIDTHS))
@pytest.mark.parametrize("kind", KINDS)
def test_no_legend_covers_data_no_entry_is_told_by_colour_alone_no_text_is_tiny_or_raw(synthetic_figures, width, kind):
    """Each kind checked in a test of its own (the figures drawn once a session): the checks of
    every kind at once took minutes on two busy cores."""
    problems = [p for fig in checks(synthetic_figures(width), (kind,), _check)[kind] for p in fig]
    assert problems == [], "\n".join(dict.fromkeys(problems))


#: the least room (pt) between a marker's or an error bar's edge and the frame of its panel
DATA_ROOM_PT = 4.0


def _data_rooms(fig) -> list[tuple[str, float]]:
    """(title, room in pt) of each visible panel with data: the least distance of its markers
    (their full size), lines, bands and error bars to the top or bottom of its frame (a table's
    cells, which fill their frame, are no data here)."""
    out = []
    for ax in (a for a in fig.axes if a.get_visible()):
        ends = []  # (lowest, highest) display y of each line's markers and of each error bar
        for line in (ln for ln in ax.get_lines() if ln.get_transform() == ax.transData and len(ln.get_xydata())):
            drawn = line.get_marker() not in (None, "None", "", " ")
            half = (line.get_markersize() + line.get_markeredgewidth()) / 2 if drawn else 0.0
            y = ax.transData.transform(line.get_xydata())[:, 1]
            ends.append((np.nanmin(y) - half * fig.dpi / 72.0, np.nanmax(y) + half * fig.dpi / 72.0))
        for c in ax.collections:
            if c.get_transform() == ax.transData and c.get_paths() and not isinstance(c, QuadMesh):
                y = ax.transData.transform(np.concatenate([p.vertices for p in c.get_paths()]))[:, 1]
                ends.append((np.nanmin(y), np.nanmax(y)))
        if ends:
            room = min(min(lo for lo, _ in ends) - ax.bbox.y0, ax.bbox.y1 - max(hi for _, hi in ends))
            out.append((ax.get_title(), room * 72.0 / fig.dpi))
    return out


@pytest.mark.parametrize("width", sorted(plots.COLUMN_WIDTHS))
@pytest.mark.parametrize("kind", [k for k in KINDS if k != "coherence"])  # coherence: a table of cells
def test_the_data_of_every_figure_clear_the_frame(synthetic_figures, width, kind):
    """Markers, lines, bands and error bars of every panel lie inside it with room (matplotlib's
    5 % margins put the lms figure's markers on its top edge and its error bars' caps 1.1 pt from
    it, coefficient and summary bands 0.7-1.9 pt, a narrow signals panel's trace 0.5 pt; the forces'
    residual markers at zero were cut by the frame, the equal axes of the orbits 2.3-3.1 pt)."""
    rooms = [room for fig in synthetic_figures(width)[kind] for room in _data_rooms(fig)]
    assert rooms, "no panel with data"
    assert [f"panel {title!r}: data {pt:.2f} pt from the frame" for title, pt in rooms if pt < DATA_ROOM_PT] == []


@pytest.mark.parametrize("width", sorted(plots.COLUMN_WIDTHS))
def test_no_magnitude_axis_ticks_below_zero(synthetic_figures, width):
    """The forces' residual panels (magnitudes) have room below zero for their markers there, and no
    tick below zero."""
    panels = [ax for fig in synthetic_figures(width)["forces"] for ax in fig.axes if "residual" in ax.get_title()]
    assert panels and all(ax.get_ylim()[0] < 0 for ax in panels)
    assert [t for ax in panels for t in ax.get_yticks() if ax.get_ylim()[0] <= t < 0] == []
