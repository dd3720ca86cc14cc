"""The report's figures write the forces on the journal, the effective damping's zero crossings
and the summary's points (by the conditions that differ) as the paper does (F$_\\mathrm{x}$, typeset through
orbitrig.analysis.typeset), each text printed at 7 pt at least; the page does the same with
<sub>, and lifts the uncertainty columns its messages name; the orbit tables keep plain names."""

from __future__ import annotations

import re

import pytest

from orbitrig.analysis.plot_marks import TRUTH_SIZES, truth_look
from orbitrig.analysis.plots import COLUMN_WIDTHS
from orbitrig.analysis.typeset import entry_math, force_html, force_math, message_html, pair_html, pair_math
from support.report_figures import checks, figure_texts, printed_pt

FX, FY = "F$_\\mathrm{x}$", "F$_\\mathrm{y}$"
#: the summary's title as the report writes it of the synthetic run (tests/report/conftest.py), up to its second line
TITLE = "Constant coefficients (kcd11) at every operating point, run run\n"
KINDS = ("forces", "lms", "signals", "coherence", "derived", "summary", "coefficients")


def test_a_force_and_a_pair_as_a_figure_and_the_page_write_them():
    assert (force_math("x"), force_math("y")) == (FX, FY)
    assert force_html("y") == "F<sub>y</sub>"
    assert [pair_math(p) for p in ("xfx", "yfx", "xfy", "yfy")] == [f"x, {FX}", f"y, {FX}", f"x, {FY}", f"y, {FY}"]
    assert pair_html("yfx") == "y, F<sub>x</sub>"


def test_a_message_on_the_page_subscripts_the_uncertainty_columns_it_names():
    said = "wls weights from the table's u_x, u_y, u_fx, u_fy (no u_* columns); columns 'u_x', 'u_fy': <zero>"
    assert message_html(said) == (
        "wls weights from the table&#x27;s u<sub>x</sub>, u<sub>y</sub>, u<sub>Fx</sub>, u<sub>Fy</sub> "
        "(no u<sub>*</sub> columns); columns &#x27;u_x&#x27;, &#x27;u_fy&#x27;: &lt;zero&gt;"  # a quoted column stays
    )
    assert message_html("a u_xy column, mu_x") == "a u_xy column, mu_x"  # no other name lifted


def test_a_message_on_the_page_writes_the_coherence_columns_it_names_as_gamma_squared():
    said = (
        "--method wls needs u_x, u_y, u_fx, u_fy columns or coherence values (gamma2_xfx, gamma2_yfx, "
        "gamma2_xfy, gamma2_yfy); the table has neither"
    )  # reduction.equation_noise's refusal
    assert message_html(said) == (
        "--method wls needs u<sub>x</sub>, u<sub>y</sub>, u<sub>Fx</sub>, u<sub>Fy</sub> columns or coherence "
        "values (\u03b3\u00b2<sub>xFx</sub>, \u03b3\u00b2<sub>yFx</sub>, \u03b3\u00b2<sub>xFy</sub>, "
        "\u03b3\u00b2<sub>yFy</sub>); the table has neither"
    )
    assert message_html("no gamma2_* columns; column 'gamma2_xfx'") == (
        "no \u03b3\u00b2<sub>*</sub> columns; column &#x27;gamma2_xfx&#x27;"  # a quoted column stays
    )
    assert message_html("gamma2_xy, my_gamma2_xfx, gamma2_xfxy") == "gamma2_xy, my_gamma2_xfx, gamma2_xfxy"


def test_the_truth_cross_has_one_look():
    assert truth_look("small", "red") == {
        "marker": "x",
        "ls": "none",
        "color": "red",
        "ms": 4.0,
        "mew": 1.0,
        "zorder": 6,
    }
    assert (truth_look("large")["ms"], truth_look("large")["mew"]) == TRUTH_SIZES["large"] == (6.0, 1.5)


def _texts(fig) -> list[tuple[str, float]]:
    return [(t.get_text(), printed_pt(t)) for t in figure_texts(fig)]


@pytest.fixture(scope="module")
def drawn(synthetic_figures):
    """{kind: [[(text, printed pt) of each text] of each figure]} of the synthetic run, double column."""
    return checks(synthetic_figures("double"), KINDS, _texts)


def _all(drawn, kind) -> list[str]:
    return [text for fig in drawn[kind] for text, _ in fig]


@pytest.mark.parametrize("kind", KINDS)
def test_no_text_prints_under_7_pt(drawn, kind):
    small = [(text, pt) for fig in drawn[kind] for text, pt in fig if pt < 7.0 - 1e-6]
    assert small == []


def test_forces_figure_names_the_forces_typeset(drawn):
    texts = _all(drawn, "forces")
    for f in (FX, FY):
        assert f"{f} amplitude" in texts and f"|{f}|  [N]" in texts and f"|\u0394{f}|  [N]" in texts
        assert f"{f} residual: |measured \u2212 reproduced| phasor" in texts


def test_lms_figure_legend_names_the_forces_typeset(drawn):
    texts = _all(drawn, "lms")
    assert {f"{f}, {d}" for f in (FX, FY) for d in ("forward", "backward")} <= set(texts)


def test_signals_figure_names_the_force_in_its_y_labels(drawn):
    for fig in drawn["signals"]:
        texts = [text for text, _ in fig]
        assert texts.count(f"{FX}  [N]") == 2 and texts.count(f"{FY}  [N]") == 2
        # each panel a letter of its own: (a) F_x, (b) F_y of both systems; (c) F_x, (d) F_y of one piezo revolution
        titles = {t[1]: t[4:] for t in texts if re.match(r"\([a-z]\) ", t)}
        assert sorted(titles) == ["a", "b", "c", "d"] and len([t for t in texts if re.match(r"\([a-z]\) ", t)]) == 4
        assert all(titles[c].startswith("both systems, ") for c in "ab"), titles
        assert all(titles[c].startswith("piezo, RMS deviation from the fundamental") for c in "cd"), titles


def test_coherence_columns_name_the_pairs_typeset(drawn):
    texts = _all(drawn, "coherence")
    for lms in ("piezo", "strain"):
        assert [f"{lms}\nx, {FX}", f"{lms}\ny, {FX}", f"{lms}\nx, {FY}", f"{lms}\ny, {FY}"] == [
            t for t in texts if t.startswith(f"{lms}\n")
        ][:4]


def test_derived_legend_names_the_zero_of_the_effective_damping(drawn):
    entry = re.compile(
        r"kc7 \(7 coef\.\): C\$_\\mathrm\{eff,xx\}\$ = 0 at [\d.]+\u00a0\u00b1\u00a0[\d.]+\u00a0Hz, \u03a9/\u03c9\u00a0\d\.\d{3}; "
        r"C\$_\\mathrm\{eff,yy\}\$ = 0 at [\d.]+\u00a0\u00b1\u00a0[\d.]+\u00a0Hz, \u03a9/\u03c9\u00a0\d\.\d{3}"
    )
    for fig in drawn["derived"]:
        assert sum(bool(entry.fullmatch(text)) for text, _ in fig) == 1
        assert not any(" zero xx " in text for text, _ in fig)


@pytest.mark.parametrize("width", sorted(COLUMN_WIDTHS))
def test_each_y_axis_of_the_derived_figure_names_its_quantity_and_unit(synthetic_figures, width):
    """As every other figure's labels, ``quantity  [unit]``: the effective damping's axes read
    ``[kN s/m]`` alone (its panel's title named it)."""
    for fig in synthetic_figures(width)["derived"]:
        labels = [ax.get_ylabel().replace("\n", " ") for ax in fig.axes if ax.get_visible()]
        c_eff = [f"C$_\\mathrm{{eff,{e}}}$  [kN s/m]" for e in ("xx", "yy")]
        assert labels == [*c_eff, "WFR  [-]", "Re H  [MN/m]", "Im H  [MN/m]"]


def test_summary_axis_names_each_point_by_the_condition_that_differs(drawn):
    """The synthetic run's points differ in static eccentricity alone: the summary names each by
    it under every lower panel, as the figures' titles write it, and the conditions they share
    under its title."""
    (summary,) = drawn["summary"]
    texts = [text for text, _ in summary]
    assert texts.count("operating point") == 4 and "operating point number" not in texts
    assert texts.count("\u03b5$_\\mathrm{s}$ = 0") == 4 and texts.count("\u03b5$_\\mathrm{s}$ = 0.15") == 4
    shared = (
        "every point at \u03c9 = 1000 rpm, \u03b5$_\\mathrm{d}$ = 0.04, p$_\\mathrm{r}$ = 0.4826 MPa, \u03b2 = 0.25"
    )
    assert [t for t in texts if t.endswith(shared)] == [f"{TITLE}{shared}"]
    assert not any("index" in t for t in texts)


def test_summary_panels_name_the_entry_with_its_unit_on_the_y_axis(drawn):
    """'K$_\\mathrm{xy}$  [MN/m]' on the summary's y axes too, as the coefficient panels: not the unit alone."""
    (summary,) = drawn["summary"]
    labels = {t for t, _ in summary if t.endswith("]")}
    expected = {f"{entry_math('K' + e)}  [MN/m]" for e in ("xx", "xy", "yx", "yy")}
    assert expected | {f"{entry_math('C' + e)}  [kN s/m]" for e in ("xx", "xy", "yx", "yy")} <= labels, labels
    assert not {"[MN/m]", "[kN s/m]"} & labels, labels


def test_page_typesets_what_the_data_files_keep_plain(synthetic_report, synthetic_run):
    page = synthetic_report.page
    assert "<th>\u03b3\u00b2 x, F<sub>x</sub></th>" in page
    assert "u<sub>Fx</sub>" in page and "u<sub>*</sub>" in page  # the fits' notes and warnings
    assert "u_fx" not in page and "u_*" not in page
    table = (synthetic_run / "coefficients.csv").read_text(encoding="utf-8")
    assert "u_*" in table and "<sub>" not in table  # the run's table keeps the warnings' plain names


def test_coefficient_panels_name_the_entry_with_its_unit_on_the_y_axis(drawn):
    """'K$_\\mathrm{xy}$  [MN/m]', not the unit alone, as the forces' panels write 'F$_\\mathrm{x}$  [N]'."""
    for fig in drawn["coefficients"]:
        labels = {t for t, _ in fig if t.endswith("]")}
        assert {f"{entry_math('K' + e)}  [MN/m]" for e in ("xx", "xy", "yx", "yy")} <= labels, labels
        assert {f"{entry_math('C' + e)}  [kN s/m]" for e in ("xx", "xy", "yx", "yy")} <= labels, labels
        assert not {"[MN/m]", "[kN s/m]", "[kg]"} & labels, labels


def test_derived_figure_says_what_h_is(drawn):
    z = entry_math
    h = f"H = ({z('Zxx')} + {z('Zyy')})/2 \u00b1 i ({z('Zyx')} \u2212 {z('Zxy')})/2"
    for fig in drawn["derived"]:
        texts = [t for t, _ in fig]
        (caption,) = [t for t in texts if t.startswith("H = ")]  # the legend's title, over the uncertainty's words
        assert caption.startswith(h) and "+ forward whirl (solid), \u2212 backward (dashed)" in caption, caption
        assert {"Re H  [MN/m]", "Im H  [MN/m]"} <= set(texts)
