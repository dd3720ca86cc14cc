"""`orbitrig compare`'s figure prints as the report's figures do (tests/report/test_report_print.py),
measured on the figure as written: every coefficient named with its subscript (K_xx, not Kxx),
the compared variable's symbol with its subscript (ε_s, not εs), no ASCII stand-in in a panel's
title or axis label, and no glyph under 7 pt: the titles' subscripts, the repeatability text
under each title, tick labels and the legend included."""

from __future__ import annotations

import re

import numpy as np
import pytest

from orbitrig.analysis.plots import style
from orbitrig.catalog.compare import Variable
from orbitrig.catalog.compare_plot import compare_figure, compare_title, repeats_text, write_figure
from orbitrig.catalog.rows import COEFFICIENTS
from support.campaign import campaign_rows
from support.report_figures import ASCII_STAND_INS, figure_texts, plain_entries, printed_pt, shown

#: the smallest text a journal prints (pt)
SMALLEST_PT = 7.0

#: a symbol's subscript printed on the line as ordinary letters: εs, εd (the paper writes ε_s)
RUN_ON_SUBSCRIPT = re.compile(r"[\u03b1-\u03c9][a-z]\b")


def _labels(fig) -> list[str]:
    """The panels' titles and axis labels as written."""
    return [t.get_text() for ax in fig.axes for t in (ax.title, ax.xaxis.label, ax.yaxis.label) if t.get_text()]


def _written(fig, tmp_path):
    """`fig` written as `orbitrig compare` writes it, then drawn at its own dpi (extents as measured)."""
    write_figure(fig, tmp_path)
    fig.canvas.draw()
    return fig


@pytest.mark.parametrize(
    "n_runs, scatter, names",
    [(3, 1.0, COEFFICIENTS[:8]), (9, 1.0, COEFFICIENTS), (3, 60.0, COEFFICIENTS), (1, 1.0, COEFFICIENTS[:3])],
)
@pytest.mark.parametrize("variable", [Variable.STATIC_ECCENTRICITY, Variable.DYNAMIC_ECCENTRICITY])
def test_names_subscripted_no_stand_in_no_glyph_under_7_pt(tmp_path, n_runs, scatter, names, variable):
    rows = campaign_rows(n_runs=n_runs, rng=np.random.default_rng(3), scatter=scatter)
    fig = _written(compare_figure(rows, variable, list(names), title="piezo kcd11: 15 rows"), tmp_path)
    assert plain_entries(fig) == []
    assert [t for t in _labels(fig) if ASCII_STAND_INS.search(shown(t)) or RUN_ON_SUBSCRIPT.search(shown(t))] == []
    small = [f"{printed_pt(t):.3g} pt: {t.get_text()!r}" for t in figure_texts(fig) if printed_pt(t) < SMALLEST_PT]
    assert small == []
    titles = [ax.get_title() for ax in fig.axes]
    assert titles[0] == "K$_\\mathrm{xx}$ [MN/m]" and len(set(titles)) == len(names)
    assert fig.axes[0].get_xlabel().endswith(f"\u03b5$_\\mathrm{{{variable.value[0]}}}$")


def test_the_repeatability_line_keeps_the_smallest_size_while_the_titles_are_lifted(tmp_path):
    """The titles and x labels are enlarged for their subscripts; the repeatability text under each
    title has none and stays at the style's smallest text, one size in every panel."""
    fig = _written(compare_figure(campaign_rows(), Variable.STATIC_ECCENTRICITY, ["Kxx", "Cyy"], title="t"), tmp_path)
    small = style().small
    assert {repeats_text(ax).get_fontsize() for ax in fig.axes} == {small}
    assert [printed_pt(ax.title) for ax in fig.axes] == [pytest.approx(small, abs=0.1)] * 2  # the subscript's
    assert min(ax.title.get_fontsize() for ax in fig.axes) > small
    assert repeats_text(fig.axes[0]).get_text().startswith("repeats: \u03c7\u00b2 = ")


def test_the_condition_legend_and_the_title_name_conditions_by_symbol_at_their_units(tmp_path):
    """Runs at two spins and two dynamic eccentricities against static eccentricity: each set of
    conditions in the legend by its symbols and values at the edges' units (rpm from the stored
    rad/s), the predicted lines likewise, the title's filter too; no identifier of the command line
    (an underscore shown) in any text, and the subscripts of legend and title lifted to 7 pt."""
    rows = []
    for spin_rpm, dynamic in ((1000.0, 0.04), (2000.0, 0.08)):
        for row in campaign_rows(n_runs=2):
            row.update(spin=spin_rpm * np.pi / 30, spin_rpm=spin_rpm, dynamic_eccentricity=dynamic)
            row.update(point=row["point"] + (10 if spin_rpm > 1000 else 0))
            rows.append(row)
    predicted = [
        {"spin_rpm": 1000.0, "dynamic_eccentricity": 0.04, "static_eccentricity": e, "Kxx": 2e7} for e in (0.0, 0.2)
    ] + [{"spin_rpm": 2000.0, "dynamic_eccentricity": 0.08, "static_eccentricity": e, "Kxx": 3e7} for e in (0.0, 0.2)]
    title = compare_title(rows, "piezo", "kcd11", "none", "ols", "recess_pressure = 482600 and matrix_name = ecc")
    assert (
        title == "Model kcd11, piezo load cells: 20 rows from 2 runs (p$_\\mathrm{r}$ = 0.4826 MPa, matrix name = ecc)"
    )
    fig = compare_figure(rows, Variable.STATIC_ECCENTRICITY, ["Kxx"], title=title, predicted=predicted)
    fig = _written(fig, tmp_path)
    texts = [t.get_text() for t in fig.legends[0].get_texts()]
    assert texts == [
        "\u03c9 = 1000 rpm, \u03b5$_\\mathrm{d}$ = 0.04",
        "\u03c9 = 2000 rpm, \u03b5$_\\mathrm{d}$ = 0.08",
        "predicted, \u03c9 = 1000 rpm, \u03b5$_\\mathrm{d}$ = 0.04",
        "predicted, \u03c9 = 2000 rpm, \u03b5$_\\mathrm{d}$ = 0.08",
        "rigA@2026-11-20T10:00:00+00:00",
        "rigA@2026-11-21T10:00:00+00:00",
    ]
    assert fig.get_suptitle() == title + "\nbars: expanded uncertainty U (k = 2)"
    assert [t.get_text() for t in figure_texts(fig) if "_" in shown(t.get_text())] == []
    small = [f"{printed_pt(t):.3g} pt: {t.get_text()!r}" for t in figure_texts(fig) if printed_pt(t) < SMALLEST_PT]
    assert small == []
