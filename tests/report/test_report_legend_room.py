"""The legend under the derived-quantity and impedance figures never covers a panel, its tick
labels or its axis labels, however many identifications it lists: the figure grows at the
bottom (the panels keep their size), and a figure reused for the next point starts at its own
size again; the forces, coefficient and summary figures are fitted in height to their legend,
no empty band above it, at both journal widths. Checked on the renderer's extents, as drawn into
the PNG."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from orbitrig.analysis import plots
from orbitrig.analysis.plots import Fitted
from orbitrig.analysis.plot_panels import LEGEND_GAP
from orbitrig.analysis.plots_derived import derived_figure, impedance_figure
from orbitrig.analysis.quality import derived_of, true_impedance
from orbitrig.analysis.report_analysis import analyse_point
from orbitrig.store.reader import read_run
from reduction.systematic import UncertaintyBasis

#: fit labels as the report writes them, 4 models x 5 frequency dependences: 20 identifications
LABELS = [
    f"{model}{fd} ({n} coef.), wls"
    for (model, n), fd in itertools.product(
        (("kc7", 7), ("kc8", 8), ("kcd11", 11), ("kcd12", 12)), ("", " power:1", " power:auto", " poly:2", " poly:3")
    )
]


@pytest.fixture(scope="module")
def point_report(synthetic_run):
    return analyse_point(read_run(synthetic_run).points[1])


def _covered(fig) -> list[str]:
    """The panels (by y label) whose extent (axes, tick labels, axis labels, title) the figure's
    legend touches, as drawn."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    (legend,) = fig.legends
    box = legend.get_window_extent(renderer)
    assert box.y0 >= fig.bbox.y0 - 0.5 and box.x0 >= -0.5 and box.x1 <= fig.bbox.x1 + 0.5  # inside the figure
    return [ax.get_ylabel() for ax in fig.axes if ax.get_visible() and box.overlaps(ax.get_tightbbox(renderer))]


def _panel_inches(fig) -> np.ndarray:
    return np.array(
        [
            [ax.get_position().width * fig.get_figwidth(), ax.get_position().height * fig.get_figheight()]
            for ax in fig.axes
        ]
    )


def _derived(point_report, n: int):
    t = point_report.point.tables["piezo"]
    d = derived_of(point_report.results["piezo"][0], t.orbit)
    return derived_figure(
        [(label, d, UncertaintyBasis.STATISTICAL) for label in LABELS[:n]], spin=t.spin, title="t\nsecond line"
    )


def _impedance(point_report, n: int):
    t = point_report.point.tables["piezo"]
    ident = point_report.results["piezo"][0].identification
    fitted = [Fitted(label, ident) for label in LABELS[:n]]
    truth = true_impedance(point_report.point.truth)
    return impedance_figure(fitted, truth, spin=t.spin, orbit=t.orbit, title="t\nsecond line")


@pytest.mark.parametrize("draw", [_derived, _impedance], ids=["derived", "impedance"])
def test_legend_of_many_fits_covers_no_panel(point_report, draw):
    small = draw(point_report, 1)
    assert _covered(small) == []
    size, panels = small.get_size_inches().copy(), _panel_inches(small)
    for n in (3, 4, 8, len(LABELS)):
        fig = draw(point_report, n)
        assert _covered(fig) == [], n
        np.testing.assert_allclose(_panel_inches(fig), panels, rtol=1e-9)  # the panels keep their size
        assert fig.get_figwidth() == size[0] and fig.get_figheight() >= size[1]
    assert draw(point_report, len(LABELS)).get_figheight() > size[1]  # room made for 7 rows of entries
    again = draw(point_report, 1)  # the same (cached) figure, for a point of one fit: its own size
    np.testing.assert_allclose(again.get_size_inches(), size)
    np.testing.assert_allclose(_panel_inches(again), panels, rtol=1e-9)
    assert _covered(again) == []


def _standard_gap(fig) -> float:
    """The room (pt) between a figure's panels and its legend under them: LEGEND_GAP with fixed
    margins; a narrow figure's constrained layout pads the legend and the panels by its h_pad each."""
    engine = fig.get_layout_engine()
    return LEGEND_GAP if engine is None else 2.0 * engine.get()["h_pad"] * 72.0


@pytest.mark.parametrize("width", sorted(plots.COLUMN_WIDTHS))
@pytest.mark.parametrize("kind", ["forces", "coefficients", "summary"])
def test_figure_height_is_fitted_to_its_legend(synthetic_figures, kind, width):
    """The forces, coefficient and summary figures at both journal widths: the figure's height
    fitted to its legend (figure_legend(fit=True)), no empty band above it: the panels' lowest text
    clears the legend by the standard gap, no more, and the legend sits on the figure's lower edge
    (was 12 pt above the legend in the coefficient figures, 16 pt in the summary, at double width).
    At double width the forces' legend (long verdict labels among its entries) lies in two columns
    across the figure, not one column with empty bands beside it. Checked as drawn into the PNG."""
    figures = synthetic_figures(width)[kind]
    assert len(figures) == {"forces": 2, "coefficients": 4, "summary": 1}[kind]  # piezo, strain (x 2 models)
    for fig in figures:
        renderer = fig.canvas.get_renderer()
        pt = 72.0 / fig.dpi
        (legend,) = fig.legends
        box = legend.get_window_extent(renderer)
        lowest = min(ax.get_tightbbox(renderer).y0 for ax in fig.axes if ax.get_visible())
        assert (lowest - box.y1) * pt == pytest.approx(_standard_gap(fig), abs=0.5)
        assert box.y0 * pt < 5.0
        if kind == "forces" and width == "double":
            assert max(len(t.get_text()) for t in legend.get_texts()) > 60  # the case that was one column
            assert box.width >= 0.7 * fig.bbox.width
