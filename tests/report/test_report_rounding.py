"""The report's tables give each number only the digits its uncertainty supports, as a journal asks:
an uncertainty to 2 significant digits with its trailing zero (0.60, not 0.6), the coefficient, its
95 % interval and its truth rounded to the decimal of its standard error; a derived quantity to the
decimal of the ± beside it. A value with 4 significant digits beside an uncertainty of 31 claims
precision the measurement does not have."""

from __future__ import annotations

import copy
import re

import pytest

from orbitrig.analysis import plots
from orbitrig.analysis.plots import coverage
from orbitrig.analysis.plots_derived import _zero_text, derived_figure
from orbitrig.analysis.report_analysis import analyse_point
from orbitrig.analysis.quality import derived_basis, derived_k
from orbitrig.analysis.report_tables import derived_table, identification_table
from orbitrig.store.reader import read_run

CELL = re.compile(r"<td>([^<]*)(?: <b>n\.d\.</b>)?</td>")


def decimals(text: str) -> int:
    """The decimal places a number is written to (0 for an integer)."""
    return len(text.split(".")[1]) if "." in text else 0


@pytest.fixture(scope="module")
def kcd11(synthetic_run):
    point = analyse_point(read_run(synthetic_run).points[1])
    return next(r for r in point.results["piezo"] if r.freq_dep == "none" and r.model == "kcd11")


def coefficient_rows(html: str) -> dict[str, list[str]]:
    """Each coefficient row's cells after the unit: value, std error, interval, ..."""
    rows = re.findall(r'<tr><th class="l">((?:(?!</th>).)*)</th><td class="l">[^<]*</td>(.*?)</tr>', html)
    return {re.sub(r"<[^>]+>", "", name): CELL.findall(cells) for name, cells in rows}


def test_a_coefficient_is_written_to_the_decimal_of_its_standard_error(kcd11):
    rows = coefficient_rows(identification_table(kcd11, {}, "kcd11", with_budget=False))
    assert len(rows) == 12, list(rows)  # Dxy and Dyx one coefficient, two entries
    for name, (value, std, interval) in rows.items():
        digits = std.replace("0.", "").lstrip("0").replace(".", "")
        assert len(digits) == 2, (name, std)  # 2 significant digits, a trailing zero kept
        lo, hi = interval.strip("[]").split(", ")
        assert decimals(value) == decimals(std) == decimals(lo) == decimals(hi), (name, value, std, interval)


def test_the_budgets_uncertainties_keep_two_significant_digits_and_the_truth_the_values_decimal(kcd11):
    r = copy.copy(kcd11)
    own = {k: 2.0 * v + 1e-3 for k, v in r.identification.coefficients.items()}
    r.stored = dict(
        r.stored or {},
        uncertainty={"k": 2.0, "systematic": {"Kxy": 600000.0}, "expanded": {"Kxy": 999600.0}},
        truth={"coefficients": own, "definition": "x"},
    )
    cells = coefficient_rows(identification_table(r, {}, "kcd11", with_budget=True))["Kxy"]
    value, _, _, systematic, expanded, k, truth = cells
    assert k == "2"
    assert (systematic, expanded) == ("0.60", "1.0")  # MN/m: not 0.6 and 1
    assert decimals(truth) == decimals(value) > 0, (value, truth)  # the truth to the value's decimal


def test_derived_quantities_have_the_decimals_of_their_uncertainty(synthetic_report):
    pairs = re.findall(r"<td>(-?[\d.]+) \u00b1 ([\d.]+)", synthetic_report.page)
    assert pairs, "no derived quantity with its uncertainty on the page"
    for value, u in pairs:
        assert decimals(value) == decimals(u), (value, u)
        assert len(u.replace(".", "").lstrip("0")) == 2, u


def test_a_zero_crossing_is_written_alike_in_the_derived_figure_and_the_table(synthetic_run):
    """The derived figure's legend and the page's table round the zero crossing of C_eff alike
    (12.19 ± 0.40 Hz, Ω/ω 0.732; the legend had 12.2 ± 0.4 Hz beside the table's 12.19 ± 0.40)."""
    point = analyse_point(read_run(synthetic_run).points[1])
    spin = point.point.settings.spin
    pairs = [(r, d) for lms in point.derived for r, d in point.derived[lms]]
    assert all(derived_k(r) == coverage() for r, _ in pairs)  # both give ± U of one k
    cells = re.findall(r"<td>([^<]*) Hz \(\u03a9/\u03c9 = ([^<)]*)\)</td>", derived_table(pairs, {}, spin))
    legend = [
        re.fullmatch(r"C\$_\\mathrm\{eff,(?:xx|yy)\}\$ = 0 at (.*)\u00a0Hz, \u03a9/\u03c9\u00a0(.*)", text).groups()
        for _, d in pairs
        for text in (_zero_text("xx", d.c_eff_zero_xx, spin), _zero_text("yy", d.c_eff_zero_yy, spin))
    ]
    assert len(cells) == len(legend) == 2 * len(pairs) >= 8
    assert [(value.replace("\u00a0", " "), ratio) for value, ratio in legend] == cells
    assert any(
        decimals(v.split(" ")[0]) == 2 and v.endswith("0") for v, _ in cells
    )  # 12.19 ± 0.40: a trailing zero kept


@pytest.mark.parametrize("bands_k", [1.0, 3.0])
def test_a_zero_crossing_takes_its_fits_k_in_the_figure_and_the_table_whatever_the_bands_k(synthetic_run, bands_k):
    """With bands of another k than the fits' U (``--coverage 1``; a Student-t fit's k beside the
    style's 2) the derived figure's legend gives each zero crossing \u00b1 the fit's own U, as the page's
    table, states that k in each entry, and states the style's k for the bands alone (it had
    \u00b1 k u of the bands' k: 12.19 \u00b1 0.20 Hz beside the table's 12.19 \u00b1 0.40 Hz at --coverage 1)."""
    point = analyse_point(read_run(synthetic_run).points[1])
    spin = point.point.settings.spin
    pairs = [(r, d) for r, d in next(iter(point.derived.values()))]
    ks = [derived_k(r) for r, _ in pairs]
    assert ks and all(k != bands_k for k in ks)
    cells = re.findall(r"<td>([^<]*) Hz \(\u03a9/\u03c9 = [^<)]*\)</td>", derived_table(pairs, {}, spin))
    plots.use_style(plots.FigureStyle(coverage=bands_k))
    try:
        fig = derived_figure(
            [(f"fit {n}", d, derived_basis(r)) for n, (r, d) in enumerate(pairs)], spin=spin, title="t", ks=ks
        )
    finally:
        plots.use_style(plots.FigureStyle())
    legend = fig.legends[0]
    entries = [t.get_text().replace("\n", " ").replace("\u00a0", " ") for t in legend.get_texts()]
    shown = [v for text in entries for v in re.findall(r"= 0 at (\S+ \u00b1 \S+) Hz", text)]
    assert shown == cells and len(cells) == 2 * len(pairs) >= 4
    assert all(f"(\u00b1U, k = {k:.3g})" in text for text, k in zip(entries, ks))
    title = legend.get_title().get_text().replace("\n", " ")
    assert "bands: \u00b1" in title and f"(k = {bands_k:g})" in title and "zero crossings:" not in title


def test_the_not_determined_note_states_the_k_its_u_was_judged_at(kcd11):
    """n.d. is judged on the stored U, of the fit's k (here a Student-t fit's, stored as a sweep
    stores a table without u columns), and the note under the table states that k, as the U
    column's head does (it said k = 2 whatever the fit's)."""
    r = copy.copy(kcd11)
    std = r.identification.std_errors
    U = {key: 2.2 * v for key, v in std.items() if v is not None}
    r.stored = dict(r.stored or {}, not_determined=["Kxy"], expanded_uncertainty={"k": 2.2, "values": U})
    k = derived_k(r)
    assert k == 2.2
    html = identification_table(r, {}, "kcd11", with_budget=False)
    assert f"n.d. = not determined: the expanded uncertainty U (k = {k:.3g}) exceeds the value." in html


def test_a_negative_number_reads_with_the_minus_sign_and_everything_else_keeps_its_hyphen():
    """Text a person reads takes the minus sign U+2212 where an ASCII hyphen stands for one; a
    date, a range of points, an exponent, a word and mathtext keep theirs (the CSV and JSON files
    are not passed through it)."""
    from orbitrig.analysis.report_html import minus_signs
    from orbitrig.analysis.rounding import typeset_minus

    m = "\u2212"
    assert typeset_minus("phase -0.35 deg, [-3.581, -3.417], (rad/s)^-1") == (
        f"phase {m}0.35 deg, [{m}3.581, {m}3.417], (rad/s)^{m}1"
    )
    kept = "2026-12-07, points 0000-0004, 1e-05, kcd11-power, a - b, -, n-1, K$_{-1}$"
    assert typeset_minus(kept) == kept
    page = '<td class="l-1">-3.499</td><pre>offset = -0.35</pre><code>run-1</code><p>k = -2</p>'
    assert (
        minus_signs(page) == f'<td class="l-1">{m}3.499</td><pre>offset = -0.35</pre><code>run-1</code><p>k = {m}2</p>'
    )
