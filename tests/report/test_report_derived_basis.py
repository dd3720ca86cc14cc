"""The derived-quantities figure's legend names the uncertainty its bands and zero crossings
rest on. Where the run stored a calibration budget they are drawn on the combined covariance
(quality.derived_basis, as the exports' derived _std and the page's table): the legend said
"statistical" there, while the band was twice as wide as the statistical one alone would be."""

from __future__ import annotations

import numpy as np
import pytest

from orbitrig.analysis import plots, report
from orbitrig.analysis.quality import derived_basis
from orbitrig.analysis.report import ReportOptions
from orbitrig.analysis.report_analysis import analyse_point
from orbitrig.store.reader import read_run
from reduction.derived import derived_quantities
from reduction.systematic import UncertaintyBasis
from support.report_synthetic import write_synthetic_run
from test_report_stated import STATED


@pytest.fixture(scope="module")
def calibrated_run(tmp_path_factory):
    return write_synthetic_run(tmp_path_factory.mktemp("calibrated") / "run", incomplete=0, calibration=STATED)


def _derived_figure(directory, monkeypatch, tmp_path):
    """The derived figure of point 1's piezo system as `orbitrig report` draws it, and the point."""
    drawn = {}
    monkeypatch.setattr(plots, "save_figure", lambda fig, path: drawn.setdefault(path.name, fig) and path)
    pr = analyse_point(read_run(directory).points[1])
    report._plot_lms(pr, "piezo", tmp_path, "where", ReportOptions(figures=frozenset({"derived"})))
    return drawn[f"derived_{pr.point.name}_piezo.png"], pr


def _legend(fig) -> str:
    """The legend title's statement of the uncertainty, after the definition of H, its lines joined."""
    title = " ".join(fig.legends[0].get_title().get_text().split("\n"))
    assert title.startswith("H = ")
    return title[title.index("bands and zero crossings") :]


def test_legend_says_combined_when_the_bands_are_combined(calibrated_run, monkeypatch, tmp_path):
    fig, pr = _derived_figure(calibrated_run, monkeypatch, tmp_path)
    assert {derived_basis(r) for r, _ in pr.derived["piezo"]} == {UncertaintyBasis.COMBINED}
    assert _legend(fig) == (
        "bands and zero crossings: \u00b1expanded uncertainty U at 95.45 % (k per coefficient: Student's t at its "
        "effective dof, as the table), combined (statistical and calibration)"
    )
    r, d = pr.derived["piezo"][0]
    statistical = derived_quantities(r.identification, d.orbit, pr.point.settings.spin)
    assert np.all(d.c_eff_xx_std > 1.05 * statistical.c_eff_xx_std)  # the band drawn is not the statistical one
    band = fig.axes[0].collections[0].get_paths()[0].vertices[:, 1]  # C_eff,xx -+ 2 u in kN s/m
    assert (
        band.max() - band.min()
        >= (np.max(d.c_eff_xx + 2 * d.c_eff_xx_std) - np.min(d.c_eff_xx - 2 * d.c_eff_xx_std)) * 1e-3 * 0.999
    )


def test_legend_says_statistical_without_a_budget(synthetic_run, monkeypatch, tmp_path):
    fig, pr = _derived_figure(synthetic_run, monkeypatch, tmp_path)
    assert {derived_basis(r) for r, _ in pr.derived["piezo"]} == {UncertaintyBasis.STATISTICAL}
    assert _legend(fig) == "bands and zero crossings: \u00b1expanded uncertainty U (k = 2), statistical"
