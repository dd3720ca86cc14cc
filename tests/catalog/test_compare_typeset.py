"""`orbitrig compare`'s figure prints as the report's figures do (tests/report/test_report_print.py),
measured on the figure as written: every coefficient named with its subscript (K_xx, not Kxx),
the compared variable's symbol with its subscript (ε_s, not εs), no ASCII stand-in in a panel's
title or axis label, and no glyph under 6 pt: the titles' subscripts, the repeatability text
under each title, tick labels and the legend included."""

from __future__ import annotations

import re

import numpy as np
import pytest

from orbitrig.analysis.plots import style
from orbitrig.catalog.compare import Variable
from orbitrig.catalog.compare_plot import compare_figure, repeats_text, write_figure
from orbitrig.catalog.rows import COEFFICIENTS
from support.campaign import campaign_rows
from support.report_figures import ASCII_STAND_INS, figure_texts, plain_entries, printed_pt, shown

#: the smallest text a journal prints (pt)
SMALLEST_PT = 6.0

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
def test_names_subscripted_no_stand_in_no_glyph_under_6_pt(tmp_path, n_runs, scatter, names, variable):
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
