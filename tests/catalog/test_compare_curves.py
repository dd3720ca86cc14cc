"""orbitrig compare joins a run's points only along the compared variable: a run of two
pressure ratios plotted against static eccentricity is two curves, one per pressure ratio."""

from __future__ import annotations

import numpy as np
from matplotlib.container import ErrorbarContainer

from support.campaign import ECCENTRICITIES, campaign_rows
from orbitrig.catalog.compare import Variable
from orbitrig.catalog.compare_plot import compare_figure

RATIOS = (0.25, 0.55)


def _two_ratio_rows() -> list[dict]:
    """Two runs, each at every eccentricity and both pressure ratios; Kxx far apart by ratio."""
    rows = []
    for ratio, base in zip(RATIOS, (3.0e7, 4.0e7)):
        for row in campaign_rows(n_runs=2):
            row.update(pressure_ratio=ratio, point=row["point"] + 10 * RATIOS.index(ratio), Kxx=base + row["Kxx"] / 1e3)
            rows.append(row)
    return rows


def test_each_run_draws_one_curve_per_set_of_the_other_conditions():
    rows = _two_ratio_rows()
    fig = compare_figure(rows, Variable.STATIC_ECCENTRICITY, ["Kxx"], title="t")
    curves = [c.lines[0] for c in fig.axes[0].containers if isinstance(c, ErrorbarContainer)]
    assert len(curves) == 2 * len(RATIOS)  # 2 runs x 2 pressure ratios, not one line per run
    for line in curves:
        x, y = (np.asarray(v, float) for v in line.get_data())
        assert len(x) == len(ECCENTRICITIES) and np.all(np.diff(x) > 0)  # along eccentricity only
        assert np.all(y < 35.0) or np.all(y > 35.0)  # MN/m: every point of one pressure ratio
    texts = [t.get_text() for t in fig.legends[0].get_texts()]
    assert {"\u03b2 = 0.25", "\u03b2 = 0.55"} <= set(texts)
    assert sum(t.startswith("rigA@") for t in texts) == 2  # each run named once


def test_one_set_of_conditions_keeps_one_curve_per_run_and_no_condition_legend():
    rows = campaign_rows(n_runs=2)
    fig = compare_figure(rows, Variable.STATIC_ECCENTRICITY, ["Kxx"], title="t")
    curves = [c for c in fig.axes[0].containers if isinstance(c, ErrorbarContainer)]
    assert len(curves) == 2
    assert not any(t.get_text().startswith("\u03b2") for t in fig.legends[0].get_texts())
