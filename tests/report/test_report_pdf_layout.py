"""report.pdf's table pages keep every table inside the page's text block
(orbitrig.analysis.report_pages): an identification table with its calibration budget and the
simulator's truth (nine columns) ran 1 pt past the A4 page's right edge at the smallest size;
its column heads are wrapped narrower first, never between a number and its %. A table's remarks
(how to read it) stay on its page."""

from __future__ import annotations

import pytest

from orbitrig.analysis.pdf_text import text_width
from orbitrig.analysis.report_pages import TEXT_PT, TablePages
from orbitrig.analysis.table_rows import Table

#: the heads of an identification table with a budget and the truth (table_rows.identification_rows)
HEAD = [
    "coefficient",
    "unit",
    "value",
    "std error\n(statistical, type A)",
    "95 % interval, statistical only\n(normal, 1.96)",
    "systematic u\n(calibration, type B)",
    "expanded U\n(combined, 95.45 %)",
    "k\n(of U)",
    "true (simulator, this model)",
]
#: the widest row the simulator's 2000 rpm point gave (kc8, piezo load cells)
ROW = ["K_{yx}", "MN/m", "-10.793", "0.092", "[-10.973, -10.614]", "0.13", "0.32", "2", "-10.760"]


def test_a_table_with_budget_and_truth_fits_the_page_at_its_size():
    pages = TablePages()
    pages.table(Table("kc8 (8 coef.), ols", HEAD, [ROW] * 8))
    lines = [li for li in pages.pages[0] if li.text and not li.rule]
    fonts = pages.fonts
    right = max(li.x + text_width(fonts[li.bold], li.text, li.size) for li in lines)
    assert right <= pages.width  # inside the text block: the page's margin kept
    cells = [li for li in lines if li.text.startswith("[")]
    assert cells and {li.size for li in cells} == {TEXT_PT}  # the heads wrapped, the text not set smaller
    heads = {li.text for li in lines if li.bold}
    assert "(combined, 95.45 %)" in heads or "95.45 %)" in heads
    assert not any(h.startswith("%") for h in heads)  # never a % alone on its line


def test_heads_wrapped_narrowest_break_between_words_only():
    """Heads wrapped to 12 characters (a table still too wide at 16) broke '(statistical, type A)'
    inside its first word, ', type A)' opening a line: a head is wrapped between its words only."""
    row = ["K_{yx}", "MN/m", "-10.79312", "0.00092", "[-10.7949212, -10.7913212]", "0.0013", "0.0032", "2.00"]
    pages = TablePages()
    pages.table(Table("kc8 (8 coef.), ols", HEAD, [row + ["-10.79000000"]] * 2))
    heads = [li.text for li in pages.pages[0] if li.bold and not li.rule][1:]  # the title first
    assert "interval," in heads and "1.96)" in heads  # the narrowest wrap (12 characters) taken
    words = {w for h in HEAD for w in h.replace(" %", "\u00a0%").split()}
    assert all(w in words for h in heads for w in h.replace(" %", "\u00a0%").split()), heads
    cells = [li for li in pages.pages[0] if li.text.startswith("[")]
    assert {li.size for li in cells} == {TEXT_PT}  # at the tables' size still


def _page_of(pages: TablePages, text: str) -> int:
    return next(n for n, lines in enumerate(pages.pages) if any(li.text.startswith(text) for li in lines))


def test_a_tables_remarks_stay_on_its_page_wherever_it_falls():
    """The derived quantities' '± k = 2 ...' (what its ± are) was left alone at the top of the next
    page: a table's remarks, how to read it, are laid out with it; its warnings and notes may follow."""
    remarks = [
        "\u00b1 k = 2 standard uncertainties (combined), linearised for WFR and the zero crossings.",
        "D is mass.",
    ]
    for filler in range(0, 90, 3):
        pages = TablePages()
        for _ in range(filler):
            pages.paragraph("a line before the table")
        pages.table(
            Table(
                "Derived quantities",
                ["identification", "WFR at 5 Hz"],
                [["kc8", "0.476 \u00b1 0.015"]] * 2,
                remarks=remarks,
                notes=["a note"],
            )
        )
        title = _page_of(pages, "Derived quantities")
        assert _page_of(pages, "\u00b1 k = 2") == _page_of(pages, "D is mass.") == title, filler
        assert _page_of(pages, "a note") in (title, title + 1)


def test_the_derived_quantities_numbers_are_flush_right_their_names_flush_left():
    """The derived table's first WFR column was set flush left, as a unit, the second flush right:
    a table of one name column (table_rows.derived_rows: names=1) sets every number flush right."""
    pages = TablePages()
    rows = [
        ["kc8 (8 coef.)", "1.058 \u00b1 0.066", "1.058 \u00b1 0.066"],
        ["kcd11 (11 coef.)", "1.06 \u00b1 0.10", "0.9 \u00b1 1.1"],
    ]
    pages.table(Table("Derived quantities", ["identification", "WFR at 5 Hz", "WFR at 20 Hz"], rows, names=1))
    fonts = pages.fonts
    edges: dict[str, tuple[float, float]] = {}
    for li in pages.pages[0]:
        if li.text and not li.rule:
            edges[li.text] = (li.x, li.x + text_width(fonts[li.bold], li.text, li.size))
    assert edges["kc8 (8 coef.)"][0] == edges["kcd11 (11 coef.)"][0] == edges["identification"][0] == 0.0
    assert edges["1.06 \u00b1 0.10"][1] == pytest.approx(edges["WFR at 5 Hz"][1])  # flush right under its head
    assert edges["0.9 \u00b1 1.1"][1] == pytest.approx(edges["WFR at 20 Hz"][1])
