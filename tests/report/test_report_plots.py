"""`orbitrig report DIR`: PNG plots and the HTML page."""

from __future__ import annotations

import re
import struct

import pytest
from typer.testing import CliRunner

from orbitrig.cli import app
from rigunits import display_unit
from orbitrig.analysis.report_analysis import analyse_point
from orbitrig.analysis.rounding import at_decimals, typeset_minus, uncertainty_decimals
from orbitrig.store.reader import read_run
from support.report_synthetic import write_synthetic_run

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def png_size(path):
    """(width, height) from the IHDR chunk, after checking the signature."""
    data = path.read_bytes()
    assert data[:8] == PNG_MAGIC, f"{path} is not a PNG"
    assert data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


def test_report_writes_every_plot(synthetic_run, synthetic_report):
    assert synthetic_report.exit_code == 0, synthetic_report.output
    assert "2 complete point(s), 1 incomplete" in synthetic_report.stdout
    assert "17 plot(s)" in synthetic_report.stdout
    assert "warning" not in synthetic_report.stderr  # stored identifications repeat exactly
    assert "point 0001 strain kcd12 poly:8 refused: " in synthetic_report.stderr  # refusals are visible
    plots = synthetic_run / "plots"
    # --point 1: nothing of point 0; Figure 4 for the lowest and highest frequency of each direction
    assert {p.name for p in plots.glob("*.png")} == {
        "forces_0001_piezo.png",
        "forces_0001_strain.png",
        "coefficients_0001_piezo_kcd11.png",
        "coefficients_0001_strain_kcd11.png",
        "coefficients_0001_piezo_kc7.png",
        "coefficients_0001_strain_kc7.png",
        "derived_0001_piezo.png",
        "derived_0001_strain.png",
        "impedance_0001_piezo.png",
        "impedance_0001_strain.png",
        "coherence_0001.png",
        "lms_0001.png",
        "orbits_0001.png",
        "signals_0001_00_fwd.png",
        "signals_0001_09_fwd.png",
        "signals_0001_00_bwd.png",
        "signals_0001_09_bwd.png",
    }
    for path in plots.glob("*.png"):
        w, h = png_size(path)
        assert w >= 800 and h >= 400
        assert path.stat().st_size > 30_000  # drawn content, not an empty canvas


def test_repeated_identifications_match_the_stored_ones(synthetic_run):
    pr = analyse_point(read_run(synthetic_run).points[0])
    assert pr.mismatches == []
    assert {(r.model, r.freq_dep) for r in pr.results["piezo"]} == {
        ("kcd11", "none"),
        ("kc7", "none"),
        ("kcd11", "power:1"),
    }


def test_repeated_identification_that_differs_is_named(synthetic_run):
    point = read_run(synthetic_run).points[0]  # a fresh copy in memory
    point.identification("piezo", "kc7", "none").result["coefficients"]["Kxy"] *= 1.01
    mismatches = analyse_point(point).mismatches
    assert len(mismatches) == 1 and mismatches[0].startswith("piezo kc7 none: Kxy stored")


def test_html_references_every_plot_and_shows_coefficients(synthetic_run, synthetic_report):
    plots = synthetic_run / "plots"
    html = synthetic_report.page
    sources = set(re.findall(r'<img src="([^"]+)"', html))
    assert sources == {p.name for p in plots.glob("*.png")}
    assert not re.search(r'(src|href)="(https?:)?//', html) and "<script" not in html  # self-contained
    text = re.sub(r"<pre.*?</pre>|<style.*?</style>|<[^>]*>", " ", html, flags=re.S)
    assert "\u22123." in text and not re.search(r"(?<![\w.-])-\.?\d", text)  # negatives read with U+2212
    pr = analyse_point(read_run(synthetic_run).points[1])
    for r in pr.results["strain"]:
        for key, value in r.identification.coefficients.items():
            unit, scale = display_unit(key)
            se = r.identification.std_errors[key] * scale
            decimals = uncertainty_decimals(se)  # the value to the decimal of its standard error
            assert typeset_minus(at_decimals(value * scale, decimals)) in html, key  # negative: U+2212
            assert at_decimals(se, decimals) in html, key
    for text in (
        "MN/m",
        "kN s/m",
        "kg",
        "stopped",
        "1 incomplete (0002)",
        "1000 rpm",
        "0.4826 MPa",
        "true (simulator)",
    ):
        assert text in html
    assert "kcd12 poly:8 refused" in html  # the sweep's refusal is shown, with its reason
    assert "<th>\u03b3\u00b2 x, F<sub>x</sub></th>" in html  # the coherence table (paper Table 1)
    assert "<th>\u03b3\u00b2 y, F<sub>y</sub></th>" in html


def test_display_units():
    assert display_unit("Kxy") == ("MN/m", 1e-6)
    assert display_unit("Cyy_2") == ("kN s/m (rad/s)^-2", 1e-3)
    assert display_unit("Dxx") == ("kg", 1.0)


@pytest.mark.parametrize(
    "point, why", [("2", "point 0002 skipped: never completed"), ("7", "point 0007 skipped: no such point in the run")]
)
def test_cli_report_point_not_complete(synthetic_run, point, why):
    result = CliRunner().invoke(app, ["report", str(synthetic_run), "--point", point, "--figures", "coefficients"])
    assert result.exit_code == 1 and f"error: {why}" in result.stderr, result.output


def test_cli_report_of_no_drawable_point_leaves_the_earlier_report(tmp_path):
    """A mistyped --point (or only damaged points) names the point, exits 1 and touches nothing
    (the quickest figure kind drawn: what is kept does not depend on the kinds)."""
    run = write_synthetic_run(tmp_path / "run", incomplete=0)
    first = CliRunner().invoke(app, ["report", str(run), "--figures", "coherence", "--formats", "png"])
    assert first.exit_code == 0, first.output
    before = {p.name: p.read_bytes() for p in (run / "plots").iterdir() if p.is_file()}
    assert {"index.html", "report.pdf", "summary.png"} <= set(before)
    result = CliRunner().invoke(app, ["report", str(run), "--point", "9", "--figures", "coherence"])
    assert result.exit_code == 1 and "error: point 0009 skipped: no such point in the run" in result.stderr
    assert {p.name: p.read_bytes() for p in (run / "plots").iterdir() if p.is_file()} == before
    assert "nothing drawn" in result.stdout, result.output
    some = CliRunner().invoke(app, ["report", str(run), "--point", "9", "--point", "1", "--figures", "coherence"])
    assert some.exit_code == 1 and "point 0009 skipped" in some.stderr, some.output
    assert "coherence_0001" in (run / "plots" / "index.html").read_text()  # as before: the page of what was drawn
    assert not (run / "plots" / "summary.png").exists()


def test_cli_report_bad_directory(tmp_path):
    result = CliRunner().invoke(app, ["report", str(tmp_path / "missing")])
    assert result.exit_code == 2 and "no such directory" in result.stderr
    (tmp_path / "run.h5").write_text("not hdf5")
    result = CliRunner().invoke(app, ["report", str(tmp_path)])
    assert result.exit_code == 2 and str(tmp_path / "run.h5") in result.stderr


def test_summary_plot_over_points(synthetic_run, tmp_path):
    from orbitrig.analysis.report import Report, summary_plot_for

    run = read_run(synthetic_run)
    report = Report(run, tmp_path, [analyse_point(p) for p in run.complete_points])
    path = summary_plot_for(report)
    assert path == tmp_path / "summary.png"
    w, h = png_size(path)
    assert w >= 800 and h >= 400 and path.stat().st_size > 30_000
    # one point only: no summary
    assert summary_plot_for(Report(run, tmp_path, report.points[:1])) is None


def test_report_of_one_point_drops_an_earlier_summary(tmp_path):
    """`report --point N` after a full report must not leave the old summary.png behind."""
    from support.report_synthetic import write_synthetic_run

    from orbitrig.analysis.report import ReportOptions, make_report

    run = write_synthetic_run(tmp_path / "run", n_points=2, incomplete=0)
    quick = ReportOptions(figures=frozenset({"lms"}))  # the summary is drawn whatever the kinds
    assert make_report(run, options=quick).summary == run / "plots" / "summary.png"
    assert (run / "plots" / "summary.png").exists()
    one = make_report(run, points=[1], options=quick)
    assert one.summary is None and not (run / "plots" / "summary.png").exists()
    assert "summary.png" not in (run / "plots" / "index.html").read_text()


def test_report_kinds_and_all_frequencies_replace_an_earlier_report(tmp_path):
    """--figures draws only those kinds and removes the point's other figures; --all-frequencies
    draws Figure 4 for every stored orbit frequency."""
    from support.report_synthetic import write_synthetic_run

    run = write_synthetic_run(tmp_path / "run", n_points=1, incomplete=0)
    stale = run / "plots" / "forces_0000_piezo.png"
    stale.parent.mkdir()
    stale.write_bytes(b"old")
    result = CliRunner().invoke(app, ["report", str(run), "--figures", "signals", "--all-frequencies"])
    assert result.exit_code == 0, result.output
    names = {p.name for p in (run / "plots").glob("*.png")}
    assert names == {f"signals_0000_{k:02d}_{d}.png" for k in range(10) for d in ("fwd", "bwd")}
    bad = CliRunner().invoke(app, ["report", str(run), "--figures", "signals,wiggles"])
    assert bad.exit_code == 2 and "unknown kind(s) wiggles" in bad.stderr


def test_every_figure_has_a_text_alternative_saying_what_and_where(synthetic_report):
    """A reader who does not see the images (a screen reader, a page without them) hears what each
    figure shows and of which point, system, model and whirl, not its file's name."""
    alts = dict(re.findall(r'<img src="([^"]+)\.png" alt="([^"]*)"', synthetic_report.page))
    assert alts and len(alts) == synthetic_report.page.count("<img ")
    assert (
        alts["coefficients_0001_piezo_kcd11"] == "Rotordynamic coefficients, point 0001, piezo load cells, model kcd11"
    )
    assert alts["forces_0001_strain"] == "Measured and reproduced forces, point 0001, strain load cells"
    assert alts["coherence_0001"] == "Coherence between motion and force signals, point 0001"
    signals = [a for stem, a in alts.items() if stem.startswith("signals_0001_") and stem.endswith("_bwd")]
    assert signals and all(
        re.fullmatch(r"Force signals, point 0001, orbit frequency no\. \d+, backward whirl", a) for a in signals
    )
    assert all(stem not in alt and "_" not in alt for stem, alt in alts.items())
