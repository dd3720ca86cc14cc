"""The report's coefficient figure marks the truth the table beside it compares with: each
fit's own truth (the true Z projected onto its model), in the fit's colour, not the constant
K0, C0, D0 best fit; kc8's own Kxx differs from K0 (its model has no D to absorb the mass)."""

from __future__ import annotations

import numpy as np

from orbitrig.analysis import plots_coefficients, report, report_analysis
from orbitrig.analysis.plots import ENTRIES
from orbitrig.analysis.reduce import own_truth
from orbitrig.analysis.typeset import entry_math
from rigunits import DISPLAY_UNITS
from orbitrig.store.reader import read_run


def test_truth_crosses_are_each_fits_own_truth(sim_run, tmp_path, monkeypatch):
    point = read_run(sim_run).points[0]
    pr = report_analysis.analyse_point(point)
    drawn = {}

    def keep(path, fitted, **kw):
        drawn[path.name] = plots_coefficients.coefficients_figure(fitted, **kw)
        return path

    monkeypatch.setattr(plots_coefficients, "coefficients_plot", keep)
    report._plot_lms(pr, "piezo", tmp_path, "here", report.ReportOptions(figures=frozenset({"coefficients"})))
    fits = {r.model: r for r in pr.results["piezo"]}
    assert {"kc8", "kcd11"} <= set(fits)
    kc8_truth = own_truth(fits["kc8"])
    k0 = np.asarray(point.truth["K0"])
    assert abs(kc8_truth["Kxx"] - k0[0, 0]) > 1e-4 * abs(k0[0, 0])  # the two truths differ
    keys = {entry_math(m + e): m + e for m in "KCD" for e in ENTRIES}  # a panel's title: its entry's name
    for model, r in fits.items():
        fig = drawn[f"coefficients_{point.name}_piezo_{model}.png"]
        truth = own_truth(r)
        for ax in (a for a in fig.axes if a.get_title()):
            name = keys[ax.get_title()]
            labels = {ln.get_label() for ln in ax.get_lines()}
            assert plots_coefficients.POINT_TRUTH_LABEL not in labels, name
            crosses = [ln for ln in ax.get_lines() if ln.get_label() == plots_coefficients.OWN_TRUTH_LABEL]
            assert len(crosses) == 1, name
            y = crosses[0].get_ydata()
            value = truth.get(name)
            if value is None:  # an entry of a constrained pair (kcd11's Dyx = Dxy)
                continue
            np.testing.assert_allclose(y, value * DISPLAY_UNITS[name[0]][1], rtol=1e-12)
    kxx = next(
        ax for ax in drawn[f"coefficients_{point.name}_piezo_kc8.png"].axes if ax.get_title() == entry_math("Kxx")
    )
    y = next(ln for ln in kxx.get_lines() if ln.get_label() == plots_coefficients.OWN_TRUTH_LABEL).get_ydata()
    assert not np.allclose(y, k0[0, 0] * DISPLAY_UNITS["K"][1], rtol=1e-6)
