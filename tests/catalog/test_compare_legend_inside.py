"""`orbitrig compare`'s legend lies inside the figure: with five runs of a rig whose run ids are
as the sweep makes them (`SAC-DS-1@2026-12-03T17:46:24.468Z`) and a predicted line, four columns
of legend were wider than the figure, and the written PNG cut the first marker and the last run
id (the reader could not tell which run the purple points were)."""

from __future__ import annotations

import numpy as np
import pytest

from orbitrig.catalog.compare import Variable
from orbitrig.catalog.compare_plot import compare_figure
from orbitrig.catalog.rows import COEFFICIENTS
from support.campaign import ECCENTRICITIES, campaign_rows


def _rows(n_runs: int, rig: str) -> list[dict]:
    rows = campaign_rows(n_runs=n_runs, rng=np.random.default_rng(5))
    for r in rows:
        run = int(r["run_path"].rsplit("/", 1)[-1])
        r["run_id"] = f"{rig}@2026-12-03T17:{37 + run:02d}:{run:02d}.{100 + run}Z"
    return rows


@pytest.mark.parametrize("n_runs, rig", [(5, "SAC-DS-1"), (8, "SAC-DS-1"), (3, "bearing-rig-hall-B-2")])
def test_legend_inside_the_figure(n_runs, rig):
    predicted = [{"static_eccentricity": e, "Kxx": 3.3e7} for e in ECCENTRICITIES]
    fig = compare_figure(
        _rows(n_runs, rig), Variable.STATIC_ECCENTRICITY, list(COEFFICIENTS[:8]), title="t", predicted=predicted
    )
    fig.draw_without_rendering()
    box = fig.legends[0].get_window_extent(fig.canvas.get_renderer())
    assert box.x0 >= 0 and box.x1 <= fig.bbox.width, (box.x0, box.x1, fig.bbox.width)
    assert box.y0 >= 0
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert len(labels) == n_runs + 1 and labels[0] == "predicted"
