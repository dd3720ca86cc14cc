"""The summary figure names its points by their operating conditions (plots_summary.point_ticks,
through typeset's one naming of a point) and keeps those names readable when a run has many
points: upright, every k-th named, none touching its neighbour; each point still ticked; each
y label clear of the panel beside it, the last name inside the figure."""

from __future__ import annotations

import copy
import dataclasses

import pytest

from orbitrig.analysis.plot_panels import AXES, LEGEND_GAP, clear_y_labels, panel_figure
from orbitrig.analysis.plots import Fitted
from orbitrig.analysis.plots_summary import OPERATING_AXIS, POINT_AXIS, point_ticks, summary_figure
from orbitrig.analysis.report_analysis import analyse_point
from orbitrig.load_systems import LMS
from orbitrig.store.reader import read_run
from rigunits import RPM

OMEGA, PR = "\u03c9", "p$_\\mathrm{r}$"


@pytest.fixture(scope="module")
def point(synthetic_run):
    return read_run(synthetic_run).complete_points[0]


def _settings(point, spins_rpm, pressures_mpa=None):
    """{index: the point's settings at each spin (rpm) and recess pressure (MPa)}."""
    s = point.settings
    pressures = pressures_mpa or [s.recess_pressure / 1e6] * len(spins_rpm)
    return {
        i: dataclasses.replace(s, spin=rpm * RPM, spin_rpm=rpm, recess_pressure=mpa * 1e6)
        for i, (rpm, mpa) in enumerate(zip(spins_rpm, pressures))
    }


def test_points_are_named_by_the_conditions_that_differ(point):
    labels, axis, shared = point_ticks(_settings(point, [1000, 2000, 3000], [0.3, 0.3, 0.5]))
    assert axis == OPERATING_AXIS
    assert labels == {
        0: f"{OMEGA} = 1000 rpm, {PR} = 0.3 MPa",
        1: f"{OMEGA} = 2000 rpm, {PR} = 0.3 MPa",
        2: f"{OMEGA} = 3000 rpm, {PR} = 0.5 MPa",
    }
    assert shared == "\u03b5$_\\mathrm{d}$ = 0.04, \u03b5$_\\mathrm{s}$ = 0, \u03b2 = 0.25"


def test_points_alike_in_every_condition_are_named_by_number(point):
    labels, axis, shared = point_ticks({3: point.settings, 7: point.settings})
    assert (labels, axis) == ({3: "0003", 7: "0007"}, POINT_AXIS)
    assert shared.startswith(f"{OMEGA} = 1000 rpm, ")


def test_many_points_are_named_upright_and_none_touches_its_neighbour(point):
    """40 points at one spin each: too many for side-by-side names in a double-column panel."""
    pr = analyse_point(point)
    fit = {lms: Fitted("kcd11", pr.results[lms][0].identification) for lms in LMS}
    n = 40
    settings = _settings(point, [500 + 100 * i for i in range(n)])
    series = {lms: [(i, fit[lms]) for i in range(n)] for lms in LMS}
    fig = summary_figure(series, [], model="kcd11", title="t", settings=settings)
    fig.canvas.draw()
    ax = fig.axes[-1]  # a lower panel
    assert list(ax.get_xticks()) == list(range(n))  # every point ticked
    shown = [t for t in ax.get_xticklabels() if t.get_text()]
    assert 5 <= len(shown) < n
    assert all(t.get_rotation() == 90 for t in shown)
    expected = point_ticks(settings)[0]
    assert [t.get_text() for t in shown] == [expected[round(t.get_position()[0])] for t in shown]
    boxes = sorted((t.get_window_extent() for t in shown), key=lambda b: b.x0)
    assert all(a.x1 < b.x0 for a, b in zip(boxes, boxes[1:]))  # no two names touch
    assert ax.get_xlabel() == OPERATING_AXIS


def test_wide_tick_labels_keep_each_y_label_off_the_panel_beside_it_and_names_inside(point):
    """K_yx of -5.4 and -10.8 MN/m (the paper scenario at 1000 and 2000 rpm) ticks -12.5 to -5.0: its
    y label ran over the K_xy panel on its left; the panels are spaced (and the last name kept
    inside the figure) so that every y label clears its neighbour by LEGEND_GAP (4 pt)."""
    pr = analyse_point(point)
    series = {}
    for lms, values in zip(LMS, ((-5.2e6, -10.8e6), (-5.4e6, -11.0e6))):
        fits = []
        for kyx in values:
            ident = copy.deepcopy(pr.results[lms][0].identification)
            ident.coefficients["Kyx"] = kyx
            fits.append(Fitted("kcd11", ident))
        series[lms] = list(enumerate(fits))
    settings = _settings(point, [1000, 2000])
    fig = summary_figure(series, [], model="kcd11", title="t", settings=settings)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    kyx = next(ax for ax in fig.axes if ax.get_title() == "K$_\\mathrm{yx}$")
    assert min(kyx.get_yticks()) < -10 and any(t.get_text().startswith("\u221210") for t in kyx.get_yticklabels())
    rows = sorted({round(ax.get_position().y0, 3) for ax in fig.axes})
    for y0 in rows:
        row = sorted((ax for ax in fig.axes if round(ax.get_position().y0, 3) == y0), key=lambda a: a.bbox.x0)
        for left, ax in zip(row, row[1:]):
            gap = (ax.get_tightbbox(renderer).x0 - left.bbox.x1) * 72.0 / fig.dpi
            assert gap >= LEGEND_GAP - 0.05, (ax.get_ylabel(), gap)
    for ax in fig.axes:
        assert ax.get_tightbbox(renderer).x1 <= fig.bbox.x1  # the last point's name inside the figure


def _gaps(fig, axes) -> list[float]:
    """pt between each panel's tight box (tick labels, y label) and the frame of the panel on its left."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    row = list(axes[0])
    return [(b.get_tightbbox(renderer).x0 - a.bbox.x1) * 72.0 / fig.dpi for a, b in zip(row, row[1:])]


def test_the_panels_are_spaced_until_each_y_label_clears_its_left_neighbour():
    """Four panels of the summary's spacing, one ticked -12.5 to -5.0 under a subscripted label: it
    reached the panel beside it; clear_y_labels widens the gaps to LEGEND_GAP, and leaves a figure
    whose labels clear as it was."""
    fig = panel_figure(13, 3.6, bottom=1.5, wspace=0.5)
    axes = fig.subplots(1, 4, squeeze=False, subplot_kw=AXES)
    for ax in axes.flat:
        ax.set_ylabel("K$_\\mathrm{yx}$  [MN/m]")
    axes[0, 2].set_ylim(-12.7, -4.2)
    axes[0, 2].set_yticks([-12.5, -10.0, -7.5, -5.0], ["\u221212.5", "\u221210.0", "\u22127.5", "\u22125.0"])
    before = _gaps(fig, axes)
    assert before[1] < LEGEND_GAP  # the case: too close
    clear_y_labels(fig, axes)
    after = _gaps(fig, axes)
    assert min(after) == pytest.approx(LEGEND_GAP, abs=0.3)
    spacing = fig.subplotpars.wspace
    clear_y_labels(fig, axes)  # clear already: unchanged
    assert fig.subplotpars.wspace == spacing
