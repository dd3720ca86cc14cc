"""The legend's room (plot_panels._room_below) is measured from each lowest panel's lower edge:
where the x tick labels show, without measuring the y tick labels and titles, which cannot be
lower. Its edge is matplotlib's tight box's, to the pixel's fraction, whatever reaches lowest: the
x tick labels, a y label longer than its panel, a text or a legend under the frame, a line not
clipped to it, no tick labels at all."""

from __future__ import annotations

import pytest

from orbitrig.analysis import plots
from orbitrig.analysis.plot_panels import AXES, _bottom
from orbitrig.analysis.grid import light_grid


def _panel(case: str):
    fig = plots.report_figure(7.2, 2.0, layout=None)
    ax = fig.subplots(1, 2, subplot_kw=AXES)[0]
    ax.plot([0, 1, 2], [1, 3, 2])
    light_grid(ax)
    ax.set_xlabel("frequency ratio \u03a9/\u03c9 [-]")
    if case == "long y label":
        ax.set_ylabel("a y label much longer than the short panel it names [MN/m]")
    if case == "text under the frame":
        ax.text(0.5, -0.9, "note", transform=ax.transAxes)
    if case == "legend under the frame":
        ax.legend(["data"], loc="upper center", bbox_to_anchor=(0.5, -0.8))
    if case == "line not clipped":
        ax.plot([0, 2], [-20, -20], clip_on=False)
        ax.set_ylim(0, 4)
    if case == "no tick labels":
        ax.xaxis.set_tick_params(labelbottom=False)
        ax.set_xlabel("")
    if case == "equal aspect":
        ax.set_aspect("equal")  # as an orbit panel
    return fig, ax


@pytest.mark.parametrize(
    "case",
    [
        "plain",
        "long y label",
        "text under the frame",
        "legend under the frame",
        "line not clipped",
        "no tick labels",
        "equal aspect",
    ],
)
def test_lower_edge_is_the_tight_box_s(case):
    fig, ax = _panel(case)
    renderer = fig.canvas.get_renderer()
    bottom = _bottom(ax, renderer)  # first: the frame as its box places it
    expected = ax.get_tightbbox(renderer).y0
    assert bottom == expected
    if case == "long y label":  # the label, not the tick labels, is the lowest text
        assert ax.yaxis.label.get_window_extent(renderer).y0 == pytest.approx(expected)
    if case == "plain":  # the x axis is
        assert ax.xaxis.get_tightbbox(renderer).y0 == pytest.approx(expected)
