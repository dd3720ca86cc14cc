"""The summary figure names its points by their operating conditions (plots_summary.point_ticks,
through typeset's one naming of a point) and keeps those names readable when a run has many
points: upright, every k-th named, none touching its neighbour; each point still ticked."""

from __future__ import annotations

import dataclasses

import pytest

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
