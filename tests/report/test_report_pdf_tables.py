"""report.pdf opens with the page's tables as text pages (orbitrig.analysis.report_pages): a reader
who has only the file reads each coefficient with its standard error and expanded U (its k), the
adequacy verdicts, the derived quantities and the two load measuring systems' consistency, as the
page gives them (one set of rows, orbitrig.analysis.table_rows), then every figure. Read back with a real PDF reader
(pypdf's text extraction)."""

from __future__ import annotations

import re

import pytest
from pypdf import PdfReader

from orbitrig import config as cfg
from orbitrig.analysis.report import ReportOptions, make_report
from orbitrig.analysis.report_pages import PAGE
from orbitrig.analysis.rounding import at_decimals, typeset_minus, uncertainty_decimals
from orbitrig.analysis.table_rows import SIGN_CONVENTION, as_html
from rigunits import display_unit
from support.report_synthetic import write_synthetic_run

#: force channels' gain uncertainty 1 %, phase 0.2 deg: a stored calibration budget, so U is stated
STATED = cfg.CalibrationUncertainty(
    probe_sensitivity_pct=0.5,
    **{f"f{a}_{lms}": cfg.ChannelUncertainty(gain_pct=1.0, phase_deg=0.2) for a in "xy" for lms in cfg.LMS},
)


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    run = write_synthetic_run(tmp_path_factory.mktemp("tables") / "run", incomplete=0, calibration=STATED)
    return make_report(run, options=ReportOptions(figures=frozenset({"coherence"})))


def _text(pages) -> str:
    return "\n".join(page.extract_text() for page in pages)


def test_the_table_pages_come_first_then_every_figure(report):
    pages = PdfReader(report.pdf).pages
    assert report.table_pages >= 2  # each point from a page of its own
    assert len(pages) == report.table_pages + len(report.plots)
    for page in pages[: report.table_pages]:  # A4 portrait, text only
        assert (float(page.mediabox.width), float(page.mediabox.height)) == PAGE
        assert list(page["/Resources"]["/XObject"]) == ["/Foot"]  # no image: the foot's text, below
    for page in pages[report.table_pages :]:  # the figures' pixels, as before
        assert "/Im0" in page["/Resources"]["/XObject"]
    text = _text(pages[: report.table_pages])
    assert [int(n) for n in re.findall(r"^Run run, point (\d{4}):", text, re.M)] == [0, 1]


def test_a_coefficients_value_and_expanded_u_read_from_the_pdf(report):
    """Kyx (negative: the minus sign U+2212) of point 1's constant kc7 fit on the piezo cells, to
    the decimal of its standard error, and its U (k = 2) to 2 significant digits, as the run stored them."""
    pr = report.points[1]
    point = pr.point
    r = next(r for r in pr.results["piezo"] if r.model == "kc7" and r.freq_dep == "none")
    unit, scale = display_unit("Kyx")
    value, std = r.identification.coefficients["Kyx"], r.identification.std_errors["Kyx"]
    budget = r.stored["uncertainty"]
    U = budget["expanded"]["Kyx"]
    assert budget["k_values"]["Kyx"] == 2 and value < 0 < std < U  # u_* columns, the rig's u exact
    value_text = typeset_minus(at_decimals(value * scale, uncertainty_decimals(std * scale)))
    u_text = at_decimals(U * scale, uncertainty_decimals(U * scale))
    text = _text(PdfReader(report.pdf).pages[: report.table_pages])
    section = text[text.index(f"Run run, point {point.name}:") :]
    section = section[section.index("kc7 (7 coef.), ols") :]
    row = next(line for line in section.splitlines() if line.startswith("Kyx "))
    cells = row.split(" ")
    assert row.startswith(f"Kyx {unit} {value_text} ") and value_text.startswith("\u2212"), row
    assert u_text in cells[len(unit.split()) + 2 :], (row, u_text)  # after the value: U among its cells
    heads = " ".join(section.split())  # a head wrapped to fit the page reads as one text
    assert "expanded U" in heads and "(combined, 95.45 %)" in heads and "(of U)" in heads
    assert cells[-2] == f"{budget['k_values']['Kyx']:.3g}", row  # the row's own k, after U (the truth last)


def test_the_verdicts_consistency_and_derived_quantities_are_the_pages(report):
    """Each adequacy verdict, and each E_n and derived quantity the page shows, stand in report.pdf too."""
    text = _text(PdfReader(report.pdf).pages[: report.table_pages])
    page = (report.directory / "index.html").read_text(encoding="utf-8")
    verdicts = [v.text for pr in report.points for vs in pr.verdicts.values() for v in vs]
    assert len(verdicts) == 4 and all(v.startswith("frequency dependence supported: ") for v in verdicts)
    assert all(typeset_minus(v) in text.replace("\n", " ") for v in verdicts)  # each fit's, under its system
    assert text.count("Two load measuring systems: consistency") == 2
    e_n = re.findall(r'<td(?: class="err")?>([+\u2212]\d+\.\d\d)</td></tr>', page)
    rows = re.findall(r"^[KCD][xy]{2} .* ([+\u2212]\d+\.\d\d)$", text, re.M)
    assert e_n and rows == e_n  # every E_n, in the page's order and sign
    derived = re.findall(r"<td>([\u2212\d.]+ \u00b1 [\d.]+(?: Hz \(\u03a9/\u03c9 = [\d.]+\))?)</td>", page)
    assert derived and all(d in text for d in derived)  # WFR and the zero crossings of C_eff, as the page rounds them
    assert text.count("Derived quantities") == 4  # each point's, of each system


def test_every_table_page_and_each_systems_tables_on_the_page_state_the_sign_convention(report):
    """At the foot of every table page of report.pdf, after its tables; on index.html under each
    system's identification tables of each point (and in the units note at the top): one text."""
    sentence = " ".join(re.sub(r"_\{([^}]*)\}", r"\1", SIGN_CONVENTION).split())  # as read back: Kxy
    assert "positive along +x and +y" in sentence and sentence.endswith("difference is piezo \u2212 strain.")
    pages = PdfReader(report.pdf).pages[: report.table_pages]
    for page in pages:
        text = " ".join(page.extract_text().split())
        assert text.endswith(sentence) and text.count("Sign convention") == 1
    assert len({page["/Resources"]["/XObject"].raw_get("/Foot").idnum for page in pages}) == 1  # written once
    page = (report.directory / "index.html").read_text(encoding="utf-8")
    systems = sum(1 for pr in report.points for results in pr.results.values() if results)
    assert systems == 4 and page.count(f'<p class="muted">{as_html(SIGN_CONVENTION)}</p>') == systems
    assert page.count(as_html(SIGN_CONVENTION)) == systems + 1


def test_the_tables_are_a_report_pdf_when_no_figure_is_drawn(synthetic_run, tmp_path):
    """`orbitrig report DIR --point 1 --figures ""`: one point (no summary figure) and no figure
    kind, as `--figures impedance` of a rig's run (no simulator truth): no figure, and report.pdf
    holds the point's tables alone; small, its two fonts subset."""
    from typer.testing import CliRunner

    from orbitrig.cli import app

    out = tmp_path / "out"
    result = CliRunner().invoke(app, ["report", str(synthetic_run), "--point", "1", "--figures", "", "--out", str(out)])
    assert result.exit_code == 0, result.output
    pdf = out / "report.pdf"
    pages = PdfReader(pdf).pages
    assert not list(out.glob("*.png")) and 2 <= len(pages) <= 8
    assert f"the tables ({len(pages)} pages) (no figure drawn) in one file: {pdf}" in result.output
    assert all(list(page["/Resources"]["/XObject"]) == ["/Foot"] for page in pages)  # text only
    text = _text(pages)
    assert text.startswith(f"orbitrig run {synthetic_run.name}\nmatrix: ")  # the run's header, then the point
    assert f"\nRun {synthetic_run.name}, point 0001:" in text and "Kyx MN/m \u2212" in text
    assert pdf.stat().st_size < 120_000  # the fonts embedded whole took 0.8 MB
    assert "The tables in one file: " in (out / "index.html").read_text(encoding="utf-8")
