"""orbitrig.analysis.typeset: an operating condition as a figure and the page write it, and
the smallest glyph of a text of several lines."""

from __future__ import annotations

import logging

import pytest

from orbitrig.analysis.typeset import CONDITIONS, condition_label, condition_math, printed_size, script_scale


@pytest.mark.parametrize(
    "column, value, math",
    [
        ("spin", 1000 * 3.141592653589793 / 30, "\u03c9 = 1000 rpm"),  # rad/s as stored, rpm at the edges
        ("spin_rpm", 20.5, "\u03c9 = 20.5 rpm"),
        ("recess_pressure", 482600.0, "p$_\\mathrm{r}$ = 0.4826 MPa"),  # Pa as stored
        ("pressure_ratio", 0.25, "\u03b2 = 0.25"),
        ("static_eccentricity", 0.15, "\u03b5$_\\mathrm{s}$ = 0.15"),
        ("dynamic_eccentricity", None, "\u03b5$_\\mathrm{d}$ = ?"),
    ],
)
def test_a_condition_by_its_symbol_at_the_edges_unit(column, value, math):
    assert condition_math(column, value) == math


def test_labels_and_the_page_write_the_same_symbols():
    assert condition_label("static_eccentricity") == "static eccentricity \u03b5$_\\mathrm{s}$"
    assert condition_label("spin") == "spin \u03c9 [rpm]"
    assert condition_label("recess_pressure") == "recess pressure p$_\\mathrm{r}$ [MPa]"
    assert [CONDITIONS[c].html() for c in ("recess_pressure", "dynamic_eccentricity", "pressure_ratio")] == [
        "p<sub>r</sub>",
        "\u03b5<sub>d</sub>",
        "\u03b2",
    ]


def test_a_title_of_several_lines_is_measured_line_by_line(caplog):
    """A figure title is its kind, then the point's conditions on a line of their own: the
    mathtext parser takes one line (a newline in it is a missing glyph, logged), as matplotlib
    draws them."""
    title = "Force signals at 5 Hz forward whirl\npoint 0000: \u03b5$_\\mathrm{d}$ = 0.04"
    with caplog.at_level(logging.WARNING, logger="matplotlib"):
        assert printed_size(title, 10.0) == pytest.approx(10.0 * script_scale())
        assert printed_size("two\nlines", 10.0) == 10.0
    assert caplog.records == []


def test_a_style_sets_the_subscripts_at_its_smallest_size_over_its_body_size():
    """plots.use_style sets mathtext's script scale with the style's text sizes (7/7.5 shipped), not
    once on import: a style of other sizes prints its subscripts at its own ratio, measured."""
    from orbitrig.analysis import plots

    assert script_scale() == pytest.approx(plots.FigureStyle().small / plots.FigureStyle().font, rel=1e-3)
    try:
        plots.use_style(plots.FigureStyle(font=8.0, small=6.0))
        assert script_scale() == pytest.approx(0.75, rel=1e-3)
        assert printed_size("K$_\\mathrm{xx}$", 8.0) == pytest.approx(6.0, rel=1e-3)
    finally:
        plots.use_style(plots.FigureStyle())
    assert script_scale() == pytest.approx(7.0 / 7.5, rel=1e-3)


def test_a_matplotlib_without_the_private_script_constant_keeps_its_own_scale(monkeypatch):
    """The script scale is a private constant of matplotlib's mathtext: a release without it must
    not break the report's import or its styles; subscripts are then mathtext's own size (0.7)."""
    from matplotlib import _mathtext

    from orbitrig.analysis import plots

    was = _mathtext.SHRINK_FACTOR
    monkeypatch.delattr(_mathtext, "SHRINK_FACTOR")
    plots.use_style(plots.FigureStyle(font=8.0, small=6.0))  # no AttributeError
    monkeypatch.setattr(_mathtext, "SHRINK_FACTOR", was, raising=False)
    plots.use_style(plots.FigureStyle())
    assert script_scale() == pytest.approx(7.0 / 7.5, rel=1e-3)
