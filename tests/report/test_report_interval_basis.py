"""The report labels its 95 % interval "statistical only" (the exports' interval_95 is value -+ U,
calibration included where stated), and gives the derived quantities on the basis the exports
give them: the combined covariance where the run stored a budget (the sweep's stored derived
_std repeated from the stored calibration parameters), k of the fit's U, said in words."""

from __future__ import annotations

import re

import numpy as np
import pytest

from orbitrig import config as cfg
from orbitrig.analysis.quality import derived_basis
from orbitrig.analysis.report import Report
from orbitrig.analysis.report_analysis import analyse_point
from orbitrig.analysis.report_html import render
from orbitrig.analysis.typeset import entry_math
from orbitrig.store.reader import read_run
from reduction.derived import derived_quantities
from reduction.systematic import UncertaintyBasis, combined_covariance
from support.report_synthetic import write_synthetic_run

STATED = cfg.CalibrationUncertainty(
    probe_sensitivity_pct=0.5,
    **{f"f{a}_{lms}": cfg.ChannelUncertainty(gain_pct=1.0, phase_deg=0.2) for a in "xy" for lms in cfg.LMS},
)


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    directory = write_synthetic_run(tmp_path_factory.mktemp("basis") / "run", incomplete=0, calibration=STATED)
    run = read_run(directory)
    pr = analyse_point(run.points[1])
    return pr, render(Report(run, directory / "plots", [pr]))


def test_interval_column_and_note_say_statistical_only(calibrated):
    pr, page = calibrated
    n = sum(len(rs) for rs in pr.results.values())
    assert n and page.count("95 % interval, statistical only<br>(normal, 1.96)") == n
    assert re.search(r"<th>95 % interval<br>", page) is None
    assert "95 % interval, statistical only (standard errors, no calibration uncertainty)" in page


def test_derived_quantities_on_the_exports_combined_basis(calibrated):
    pr, page = calibrated
    r = pr.results["piezo"][0]
    stored = r.stored["derived"]
    assert stored["covariance"] == "combined" and derived_basis(r) is UncertaintyBasis.COMBINED
    u = r.stored["uncertainty"]
    cov = combined_covariance(r.identification, r.point.tables["piezo"], u["sources"], np.array(u["source_std"]))
    grid = 2 * np.pi * np.asarray(stored["orbit_hz"])
    d = derived_quantities(r.identification, grid, r.point.settings.spin, cov=cov)
    np.testing.assert_allclose(d.c_eff_xx_std, stored["c_eff_xx_std"], rtol=1e-6)
    np.testing.assert_allclose(d.wfr_std, stored["wfr_std"], rtol=1e-6)
    statistical = derived_quantities(r.identification, grid, r.point.settings.spin)
    assert np.all(d.c_eff_xx_std > statistical.c_eff_xx_std)  # the calibration part adds
    table_d = next(dd for rr, dd in pr.derived["piezo"] if rr is r)
    ref = derived_quantities(r.identification, table_d.orbit, r.point.settings.spin, cov=cov)
    np.testing.assert_allclose(table_d.wfr_std, ref.wfr_std, rtol=1e-12)
    note = re.search(r"\u00b1 k = 2 standard uncertainties \(combined: [^<]*</p>", page)
    assert note is not None and "statistical only" not in note.group(0), page[-3000:]


def test_coefficient_bands_rest_on_the_combined_covariance_as_the_tables_u(calibrated):
    """The paper's Figs. 6/7, the summary and the load measuring systems' bars draw U on the same basis as the tables and exports:
    k times the combined standard uncertainty where the run stored a budget; the legend says so."""
    from matplotlib.figure import Figure

    from orbitrig.analysis import plots_coefficients, plots_lms
    from orbitrig.analysis.report import _fitted
    from orbitrig.load_systems import LoadSystem

    pr, _ = calibrated
    r = next(r for r in pr.results["piezo"] if r.freq_dep == "none")
    fit = _fitted(pr, r)
    u = r.stored["uncertainty"]
    cov = combined_covariance(r.identification, r.point.tables["piezo"], u["sources"], np.array(u["source_std"]))
    assert fit.basis is UncertaintyBasis.COMBINED and np.allclose(fit.covariance, cov, rtol=1e-12)
    table = r.point.tables["piezo"]
    fig = plots_coefficients.coefficients_figure([fit], spin=table.spin, orbit=table.orbit, truth=None, title="t")
    assert "combined (statistical and calibration)" in fig.legends[0].get_title().get_text()
    kxx = next(ax for ax in fig.axes if ax.get_title() == entry_math("Kxx"))
    (band,) = kxx.collections
    y = band.get_paths()[0].vertices[:, 1]
    half = (y.max() - y.min()) / 2 / 1e-6  # N/m, the band of a constant fit
    stored_u = r.stored["expanded_uncertainty"]["values"]["Kxx"]
    assert half == pytest.approx(stored_u, rel=1e-6)  # the tables' and exports' U of Kxx
    assert half > 2 * r.identification.std_errors["Kxx"] * 1.01  # more than the statistical part
    assert plots_coefficients.constant_std(fit, "K", "xx") == pytest.approx(stored_u / 2, rel=1e-6)
    bars = Figure().subplots(1, 2)  # the load measuring systems' bars: the same U
    plots_lms._coefficient_bars(bars, {LoadSystem.PIEZO: fit, LoadSystem.STRAIN: fit})
    (kxx_bar, *_) = next(c for c in bars[0].containers if hasattr(c, "errorbar")).errorbar.lines[2][0].get_segments()
    assert np.ptp(kxx_bar[:, 1]) / 2 / 1e-6 == pytest.approx(stored_u, rel=1e-6)
