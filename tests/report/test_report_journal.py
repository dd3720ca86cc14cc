"""The report for a journal: truth crosses on every coefficient figure of a simulator run, one
uncertainty convention (k u, stated), fits solid only over the tested range, residual panels,
PNG (300 dpi) beside PDF and SVG at a column's width, report.pdf, parallel points, progress."""

from __future__ import annotations

import io
import struct

import numpy as np
import pytest
from pypdf import PdfReader

from orbitrig.analysis import plot_marks, plots, plots_coefficients, plots_forces
from rigunits import DISPLAY_UNITS
from orbitrig.analysis.report import ReportOptions, make_report
from orbitrig.analysis.report_analysis import analyse_point, fit_label
from orbitrig.analysis.typeset import entry_math
from orbitrig.analysis.plots import ENTRIES
from orbitrig.cli.report_progress import ReportProgress
from orbitrig.store.reader import read_run

FMT = plots.FigureFormat


@pytest.fixture(scope="module")
def point(synthetic_run):
    pt = read_run(synthetic_run).points[0]
    return pt, analyse_point(pt)


def _fitted(pr, lms="piezo", model="kcd11"):
    return [plots.Fitted(fit_label(r), r.identification) for r in pr.results[lms] if r.model == model]


def _coefficients(pt, pr, truth):
    table = pt.tables["piezo"]
    return plots_coefficients.coefficients_figure(
        _fitted(pr), spin=table.spin, orbit=table.orbit, truth=truth, title="t"
    )


@pytest.mark.parametrize("stored", ["per row", "constant best fit only"])
def test_truth_crosses_on_every_coefficient_panel(point, stored):
    """The simulator stores K0, C0, D0 (the per-row K, C, D only in some runs): crosses either way."""
    pt, pr = point
    truth = dict(pt.truth)
    if stored != "per row":
        for m in "KCD":
            truth.pop(m)
    fig = _coefficients(pt, pr, truth)
    axes = [ax for ax in fig.axes if ax.get_title()]
    assert len(axes) == 12  # K, C, D of kcd11
    tested = np.unique(np.round(np.abs(pt.tables["piezo"].orbit) / pt.tables["piezo"].spin, 9))
    names = {entry_math(m + e): (m, divmod(n, 2)) for m in "KCD" for n, e in enumerate(ENTRIES)}
    assert sorted(ax.get_title() for ax in axes) == sorted(names)  # each entry named as the page writes it
    for ax in axes:
        m, (i, j) = names[ax.get_title()]
        crosses = [ln for ln in ax.get_lines() if ln.get_label() == plots_coefficients.POINT_TRUTH_LABEL]
        assert len(crosses) == 1, ax.get_title()
        x, y = crosses[0].get_data()
        assert np.allclose(np.unique(np.round(x, 9)), tested)
        assert np.allclose(y, truth[f"{m}0"][i][j] * DISPLAY_UNITS[m][1])
        lo, hi = ax.get_ylim()
        assert lo < y.min() and y.max() < hi


@pytest.mark.parametrize("k", [2.0, 1.0])
def test_bands_are_k_standard_uncertainties_and_say_so(point, k):
    pt, pr = point
    plots.use_style(plots.FigureStyle(coverage=k))
    try:
        fig = _coefficients(pt, pr, pt.truth)
    finally:
        plots.use_style(plots.FigureStyle())
    title = fig.legends[0].get_title().get_text()
    assert f"(k = {k:g})" in title and ("expanded uncertainty U" if k == 2 else "standard uncertainty u") in title
    ident = _fitted(pr)[1].identification  # power:1: error bars at the tested frequencies
    kxx = next(ax for ax in fig.axes if ax.get_title() == entry_math("Kxx"))
    bars = [c for c in kxx.collections if type(c).__name__ == "LineCollection"]
    tested = np.unique(np.round(np.abs(pt.tables["piezo"].orbit), 9))
    half = np.array([abs(seg[1, 1] - seg[0, 1]) / 2 for seg in bars[0].get_segments()])
    expected = k * plots_coefficients.entry_std(ident, "K", "xx", tested) * 1e-6
    assert np.allclose(half, expected, rtol=1e-6)


def test_fits_are_solid_only_over_the_tested_range(point):
    pt, pr = point
    fig = _coefficients(pt, pr, None)
    table = pt.tables["piezo"]
    lo, hi = (f(np.abs(table.orbit)) / table.spin for f in (np.min, np.max))
    ax = next(ax for ax in fig.axes if ax.get_title() == entry_math("Cxy"))
    solid = [ln for ln in ax.get_lines() if ln.get_linestyle() == "-" and ln.get_label().startswith("kcd11")]
    dotted = [ln for ln in ax.get_lines() if ln.get_linestyle() == ":"]
    assert len(solid) == 2 and len(dotted) == 4  # each fit: solid inside, dotted from 0 and past the highest
    for ln in solid:
        assert ln.get_xdata().min() == pytest.approx(lo) and ln.get_xdata().max() == pytest.approx(hi, rel=0.01)
    for ln in dotted:
        x = ln.get_xdata()
        assert x.max() <= lo + 1e-9 or x.min() >= hi - 1e-9


def test_residual_panels_show_measured_minus_reproduced(point):
    pt, pr = point
    table = pt.tables["piezo"]
    fitted = _fitted(pr, model="kc7")
    fig = plots_forces.forces_figure(table, fitted, title="t")
    ax = next(
        ax for ax in fig.axes if ax.get_title() == "F$_\\mathrm{y}$ residual: |measured \u2212 reproduced| phasor"
    )
    ratio = table.orbit / table.spin
    forward = np.flatnonzero(plot_marks.whirl_direction(table) == 1)
    forward = forward[np.argsort(ratio[forward])]
    rep = fitted[0].identification.reproduce(table)[1]
    lines = [ln for ln in ax.get_lines() if ln.get_linestyle() == "-" and ln.get_gid() != "measured-uncertainty"]
    assert np.allclose(lines[0].get_ydata(), np.abs(table.fy - rep)[forward])
    u = [ln for ln in ax.get_lines() if ln.get_gid() == "measured-uncertainty"]
    assert len(u) == 2 and np.allclose(u[0].get_ydata(), 2.0 * table.u[forward, 3])  # U = 2 u per frequency
    assert "U = 2 u of the measured phasor" in [t.get_text() for t in fig.legends[0].get_texts()]
    assert not any("phase" in a.get_title() for a in fig.axes)


def _png_width_and_dpi(path):
    data = path.read_bytes()
    width = struct.unpack(">I", data[16:20])[0]
    at = data.index(b"pHYs")
    ppm = struct.unpack(">I", data[at + 4 : at + 8])[0]
    return width, ppm * 0.0254


def _check_files(png, inches):
    for fmt in (FMT.PDF, FMT.SVG):
        assert png.with_suffix(f".{fmt}").stat().st_size > 5_000
    w, dpi = _png_width_and_dpi(png)
    assert dpi == pytest.approx(300, abs=1) and w == pytest.approx(inches * 300, abs=2)
    page = PdfReader(png.with_suffix(".pdf")).pages[0]
    assert float(page.mediabox.width) == pytest.approx(inches * 72, abs=1)  # vector, the column's width


def test_single_column_width(point, tmp_path):
    from orbitrig.analysis.plots_coherence import coherence_figure, coherence_table

    pt, _ = point
    plots.use_style(plots.FigureStyle(width=plots.COLUMN_WIDTHS["single"], formats=tuple(FMT)))
    try:
        png = plots.save_figure(coherence_figure(coherence_table(pt.tables), title="t"), tmp_path / "c.png")
    finally:
        plots.use_style(plots.FigureStyle())
    _check_files(png, 85 / 25.4)  # the single column's print width


def test_formats_sizes_and_the_combined_pdf(tmp_path):
    from support.report_synthetic import write_synthetic_run

    run = write_synthetic_run(tmp_path / "run", n_points=2, incomplete=0)
    inches = plots.COLUMN_WIDTHS["double"]
    calls = []
    style = plots.FigureStyle(width=inches, formats=(FMT.PNG, FMT.PDF, FMT.SVG))  # vector: asked for
    options = ReportOptions(figures=frozenset({"lms"}), style=style)
    report = make_report(run, options=options, workers=2, progress=lambda *a: calls.append(a))
    assert [c[:2] for c in sorted(calls)] == [(1, 2), (2, 2)] and calls[-1][2] == len(report.plots) - 1
    for png in report.plots:
        _check_files(png, inches)
    combined = PdfReader(report.pdf)
    tables = report.table_pages  # the tables' A4 pages first, then every figure, the summary included, vector
    assert tables >= 2 and len(combined.pages) == tables + len(report.plots)
    widths = [float(p.mediabox.width) for p in combined.pages]
    assert widths == pytest.approx([595] * tables + [inches * 72] * 3, abs=1)
    assert [o.title for o in combined.outline] == ["tables", "lms_0000", "lms_0001", "summary"]
    assert [p.name for p in report.plots] == ["lms_0000.png", "lms_0001.png", "summary.png"]


def test_progress_is_one_closing_line_when_not_a_terminal():
    out = io.StringIO()
    with ReportProgress(3, stream=out) as progress:
        for k in range(1, 4):
            progress(k, 3, 17 * k)
    lines = out.getvalue().splitlines()
    assert len(lines) == 1 and lines[0].startswith("report: 3 of 3 point(s), 51 figure(s) drawn in ")


def test_width_names_a_journal_s_print_width_in_millimetres_or_inches():
    """--width double and single are a journal's 175 mm page and 85 mm column (placed there, a
    figure prints its 7 pt text at 7 pt: drawn 7.2 in wide, it printed at 6.7 pt); a width is
    also taken in millimetres or inches."""
    from orbitrig.cli.report import _style

    assert _style("double", "png", 2.0).width * 25.4 == pytest.approx(175.0)
    assert _style("single", "png", 2.0).width * 25.4 == pytest.approx(85.0)
    assert _style("170mm", "png", 2.0).width == pytest.approx(170 / 25.4)
    assert _style("6.5", "png", 2.0).width == pytest.approx(6.5)
