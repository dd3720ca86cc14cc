"""The two load measuring systems' consistency table writes each system's coefficient as that
system's identification table does, to the decimal of its standard error (it gave 4 significant
digits: 107 beside 107.0, -0.7143 beside -0.7 n.d.), and its sentence in the page's symbols."""

from __future__ import annotations

import pytest

from orbitrig.analysis.quality import LmsComparison, lms_normalised_difference
from orbitrig.analysis.report_analysis import analyse_point, fit_label, preferred
from orbitrig.analysis.table_rows import consistency_rows, identification_rows
from orbitrig.store.reader import read_run
from reduction.systematic import UncertaintyBasis


@pytest.fixture(scope="module")
def pair(synthetic_run):
    found = preferred(analyse_point(read_run(synthetic_run).points[1]))
    return found["piezo"], found["strain"]


def test_each_systems_value_reads_as_its_identification_table(pair):
    a, b = pair
    comparison = LmsComparison(lms_normalised_difference(a, b), UncertaintyBasis.STATISTICAL, stored=False)
    table = consistency_rows(a, b, comparison, fit_label(a))
    own = [
        {row[0]: row[2].removesuffix(" n.d.") for row in identification_rows(r, {}, fit_label(r), False).rows}
        for r in (a, b)
    ]
    assert len(table.rows) == len(own[0]) >= 7
    for row in table.rows:
        assert (row[2], row[3]) == (own[0][row[0]], own[1][row[0]]), row
    remark = table.remarks[0]
    assert "E_{n} = (a \u2212 b) / u(a \u2212 b)" in remark and "|E_{n}| = " in remark and "\u0160id\u00e1k" in remark
    assert "\u03c7\u00b2 = " in remark and "chi2" not in remark and "<=" not in remark
