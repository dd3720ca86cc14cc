"""The figures' bands and error bars of a combined U take each coefficient's own k, as the
table's U (fit_record.expanded_ks: Student's t at 95.45 % at its effective dof); they were drawn
at the report's --coverage k (2) for every coefficient, the legend saying "k = 2". --coverage
stays the k of a statistical-only band."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from orbitrig.analysis import plots
from orbitrig.analysis.plots import Fitted, entry_k
from orbitrig.analysis.plots_coefficients import constant_std
from orbitrig.analysis.plots_summary import summary_figure
from orbitrig.analysis.report_analysis import analyse_point
from orbitrig.store.reader import read_run
from reduction.systematic import UncertaintyBasis


@pytest.fixture(scope="module")
def fit(synthetic_run):
    point = read_run(synthetic_run).points[1]
    return point, analyse_point(point).results["piezo"][0].identification


def _bars(fig, col: int) -> np.ndarray:
    """Half-lengths of the error bars of panel `col` of the K row (display units)."""
    segs = fig.axes[col].containers[0].lines[2][0].get_segments()
    return np.array([abs(s[1, 1] - s[0, 1]) / 2 for s in segs])


def test_each_coefficient_bar_at_its_own_k(fit):
    point, ident = fit
    ks = {key: 2.0 for key in ident.coefficients} | {"Kxx": 3.18, "Kxy": 2.52}
    own = Fitted("kc7", ident, basis=UncertaintyBasis.COMBINED, ks=ks)
    assert entry_k(own, "K", "xx") == 3.18 and entry_k(own, "K", "yy") == 2.0
    settings = {i: point.settings for i in (1, 2)}
    fig = summary_figure({"piezo": [(1, own), (2, own)]}, [], model="kc7", title="t", settings=settings)
    for col, (e, k) in enumerate((("xx", 3.18), ("xy", 2.52), ("yx", 2.0))):
        assert _bars(fig, col)[0] == pytest.approx(k * constant_std(own, "K", e) * 1e-6, rel=1e-9)
    title = " ".join(fig.legends[0].get_title().get_text().split())
    assert "U at 95.45 % (k per coefficient" in title and "k = 2" not in title


def test_an_order_sum_takes_its_largest_k_and_statistical_bands_the_coverage(fit):
    _, ident = fit
    orders = Fitted("f", ident, basis=UncertaintyBasis.COMBINED, ks={"Kxx": 2.1, "Kxx_1": 2.6, "Kxy": 9.0})
    assert entry_k(orders, "K", "xx") == 2.6  # the largest of its orders'
    statistical = Fitted("s", ident)
    old = plots.style()
    try:
        plots.use_style(dataclasses.replace(old, coverage=1.0))  # --coverage 1
        assert entry_k(statistical, "K", "xx") == 1.0
        assert entry_k(orders, "K", "xx") == 2.6  # a combined band keeps its own k
        label = plots.style().band_label(bases=[UncertaintyBasis.COMBINED, UncertaintyBasis.STATISTICAL])
        assert label.endswith("; \u00b1standard uncertainty u (k = 1), statistical")
    finally:
        plots.use_style(old)
