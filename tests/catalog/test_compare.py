"""orbitrig compare: repeatability chi2 (statistically), predicted CSV, the PNG and PDF."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.transforms import Bbox
from scipy.stats import chi2
from typer.testing import CliRunner

from support.campaign import ECCENTRICITIES, campaign_rows, law
from orbitrig.catalog.compare import Variable, repeatability
from orbitrig.catalog.compare_plot import compare_figure, compare_title, repeats_text
from orbitrig.catalog.predicted import PredictedError, read_predicted
from orbitrig.catalog.rows import COEFFICIENTS
from orbitrig.catalog.store import Catalog
from orbitrig.cli import app


def test_chi2_of_two_repeats_by_hand():
    rows = campaign_rows(n_runs=2)[:1] + campaign_rows(n_runs=2)[len(ECCENTRICITIES) :][:1]
    rows[0].update(Kxx=1.0, Kxx_U=2.0)
    rows[1].update(Kxx=3.0, Kxx_U=2.0)  # u = 1 each: mean 2, chi2 = 1 + 1 on 1 dof
    rep = repeatability(rows, "Kxx")
    assert (rep.chi2, rep.dof, rep.groups) == (pytest.approx(2.0), 1, 1)
    assert rep.p_value == pytest.approx(chi2.sf(2.0, 1))


def test_repeats_scattered_as_their_u_pass_and_larger_scatter_fails():
    """300 campaigns of 3 runs x 5 points: p < 0.05 in 5 % of them (3 sigma band 1.2 - 8.8 %),
    mean chi2/dof 1 (+-0.03, 3 sigma ~ 0.02); runs scattered 3x their U fail almost always."""
    rng = np.random.default_rng(11)
    reps = [repeatability(campaign_rows(rng=rng), "Kxy") for _ in range(300)]
    assert all(r.dof == 10 and r.groups == 5 for r in reps)
    assert 0.012 <= np.mean([r.p_value < 0.05 for r in reps]) <= 0.088
    assert np.mean([r.chi2 / r.dof for r in reps]) == pytest.approx(1.0, abs=0.03)
    wide = [repeatability(campaign_rows(rng=rng, scatter=3.0), "Kxy") for _ in range(50)]
    assert np.mean([r.p_value < 0.05 for r in wide]) >= 0.95


def _predicted_csv(path, header_unit="N/m"):
    lines = ["# bulk-flow code, 1000 rpm", f"static_eccentricity,spin_rpm,Kxx [{header_unit}],Cxx [N s/m]"]
    lines += [f"{e},1000,{law('Kxx', e)},{law('Cxx', e)}" for e in np.linspace(0, 0.4, 9)]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_predicted_csv_columns_and_errors(tmp_path):
    table = read_predicted(_predicted_csv(tmp_path / "p.csv"))
    assert len(table) == 9 and table[4]["Kxx"] == pytest.approx(law("Kxx", 0.2))
    with pytest.raises(PredictedError, match=r"p2.csv, line 2, column 'Kxx \[MN/m\]': the unit of Kxx is 'N/m' \(SI\)"):
        read_predicted(_predicted_csv(tmp_path / "p2.csv", "MN/m"))
    (tmp_path / "p4.csv").write_text("static_eccentricity,Kzz [N/m]\n0.1,3e7\n")
    with pytest.raises(PredictedError, match=r"p4.csv, line 1, column 'Kzz \[N/m\]': not one of spin_rpm"):
        read_predicted(tmp_path / "p4.csv")
    (tmp_path / "p5.csv").write_text("static_eccentricity,Kxx [N/m],Kxx [N/m]\n0.1,3e7,1\n")
    with pytest.raises(PredictedError, match=r"p5.csv, line 1, column 'Kxx \[N/m\]': the column appears twice"):
        read_predicted(tmp_path / "p5.csv")
    (tmp_path / "p3.csv").write_text("static_eccentricity,Kxx [N/m]\n0.1,abc\n")
    with pytest.raises(PredictedError, match=r"p3.csv, line 2, column 'Kxx': 'abc'"):
        read_predicted(tmp_path / "p3.csv")


def test_compare_writes_png_and_pdf(tmp_path):
    Catalog(f"sqlite:///{tmp_path / 'catalog.sqlite'}").add(campaign_rows())
    runner = CliRunner()
    res = runner.invoke(
        app,
        [
            "compare",
            "--runs",
            str(tmp_path),
            "--coefficients",
            "Kxx,Cxx",
            "--predicted",
            str(_predicted_csv(tmp_path / "p.csv")),
            "--out",
            str(tmp_path / "fig"),
            "--where",
            "static_eccentricity <= 0.3",
        ],
    )
    assert res.exit_code == 0, res.output
    assert (tmp_path / "fig" / "compare.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (tmp_path / "fig" / "compare.pdf").read_bytes()[:5] == b"%PDF-"
    assert not list((tmp_path / "fig").glob("*.tmp"))
    for args, says in (
        (["--against", "load"], "--against 'load'"),
        (["--coefficients", "Kzz"], "Kzz"),
        (["--model", "kc7"], "no catalog rows"),
    ):
        bad = runner.invoke(app, ["compare", "--runs", str(tmp_path), "--out", str(tmp_path / "x"), *args])
        assert bad.exit_code == 2 and says in bad.output


def test_predicted_file_without_the_compared_variable_is_refused(tmp_path):
    Catalog(f"sqlite:///{tmp_path / 'catalog.sqlite'}").add(campaign_rows())
    predicted = tmp_path / "p.csv"
    predicted.write_text("Kxx [N/m]\n3e7\n")
    with pytest.raises(PredictedError, match=r"p.csv, line 1: no column 'spin_rpm' \(needed for --against spin\)"):
        read_predicted(predicted, Variable.SPIN)
    for against, column in (("spin", "spin_rpm"), ("static_eccentricity", "static_eccentricity")):
        res = CliRunner().invoke(
            app,
            ["compare", "--runs", str(tmp_path), "--against", against, "--lms", "piezo", "--model", "kcd11"]
            + ["--predicted", str(predicted), "--out", str(tmp_path / "fig")],
        )
        assert res.exit_code == 2 and str(predicted) in res.output and f"no column {column!r}" in res.output
    assert not (tmp_path / "fig").exists()


def test_a_lone_predicted_value_is_drawn_as_a_marker():
    predicted = [{"static_eccentricity": 0.2, "Kxx": 3.5e7, "Cxx": float("nan")}]
    fig = compare_figure(campaign_rows(), Variable.STATIC_ECCENTRICITY, ["Kxx", "Cxx"], title="t", predicted=predicted)
    kxx, cxx = fig.axes[:2]
    (line,) = [a for a in kxx.get_lines() if a.get_label() == "predicted"]
    assert line.get_visible() and line.get_marker() not in (None, "", " ", "None") and line.get_markersize() > 0
    assert list(line.get_xdata()) == [0.2] and list(line.get_ydata()) == [pytest.approx(35.0)]  # MN/m
    assert not [a for a in cxx.get_lines() if a.get_label() == "predicted"]  # an empty cell is no prediction


def test_title_counts_rows_and_runs_in_the_singular_and_plural():
    one = compare_title(campaign_rows(n_runs=1)[:1], "piezo", "kcd11", "none", "ols")
    assert one == "Model kcd11, piezo load cells: 1 row from 1 run"
    many = compare_title(campaign_rows(), "piezo", "kcd11", "power:1", "ols", "spin_rpm = 1000")
    assert many == (
        "Model kcd11 power:1, piezo load cells: 15 rows from 3 runs (\u03c9 = 1000 rpm)\n"
        "constant terms (\u03a9\u2070) of a frequency-dependent fit"
    )


def test_title_names_the_fit_and_the_filter_in_words_and_symbols():
    """No option or column name of the command line in the title: the method when it is not ols,
    the filter's operating conditions by their symbols at the edges' units (the recess pressure
    given in Pa reads in MPa, a spin in rad/s in rpm), another column in words."""
    where = (
        "matrix_name = eccentricity and pressure_ratio != 0.4 and recess_pressure >= 482600 "
        "and static_eccentricity <= 0.2 and spin > 104.71975511965977"
    )
    title = compare_title(campaign_rows(), "strain", "kc8", "none", "wls", where)
    assert title == (
        "Model kc8, wls, strain load cells: 15 rows from 3 runs (matrix name = eccentricity, \u03b2 \u2260 0.4, "
        "p$_\\mathrm{r}$ \u2265 0.4826 MPa, \u03b5$_\\mathrm{s}$ \u2264 0.2, \u03c9 > 1000 rpm)"
    )
    assert "_" not in title.replace("$_", "")  # only mathtext subscripts


def _overlaps(fig) -> list[str]:
    """Every clash of a panel title (with the repeatability text under it) with the tick labels
    or x label of the panel above or beside it, with their titles or the figure title; of the
    legend with a panel; of a panel with the figure's edge. Measured on the figure's renderer
    after drawing."""
    fig.draw_without_rendering()
    renderer = fig.canvas.get_renderer()
    place = {(ax.get_subplotspec().rowspan.start, ax.get_subplotspec().colspan.start): ax for ax in fig.axes}
    head, legend = fig._suptitle.get_window_extent(renderer), fig.legends[0].get_window_extent(renderer)
    found = []
    for (row, col), ax in place.items():
        title, panel = Bbox.union([t.get_window_extent(renderer) for t in _heads(ax)]), ax.get_tightbbox(renderer)
        if ax.title.get_window_extent(renderer).overlaps(repeats_text(ax).get_window_extent(renderer)):
            found.append(f"title of panel {row},{col} on its repeatability text")
        for where in ((row - 1, col), (row, col - 1), (row, col + 1)):  # above, left, right
            other = place.get(where)
            if other is None:
                continue
            text = [other.xaxis, other.yaxis, *_heads(other)]  # tick labels and axis labels, title
            if any(title.overlaps(t.get_tightbbox(renderer)) for t in text):
                found.append(f"title of panel {row},{col} on panel {where}")
        if title.overlaps(head):
            found.append(f"title of panel {row},{col} on the figure title")
        if legend.overlaps(panel):
            found.append(f"legend on panel {row},{col}")
        if panel.x0 < 0 or panel.y0 < 0 or panel.x1 > fig.bbox.width or panel.y1 > fig.bbox.height:
            found.append(f"panel {row},{col} past the figure's edge")
    return found


def _heads(ax) -> list:
    """The texts over a panel: its title and the repeatability text under it."""
    return [ax.title, repeats_text(ax)]


@pytest.mark.parametrize(
    "n_runs, scatter, names, title",
    [
        (3, 1.0, COEFFICIENTS[:8], "Model kcd11, piezo load cells: 15 rows from 3 runs"),  # the default 2 x 4
        (9, 1.0, COEFFICIENTS, "Model kcd11 power:1, piezo: 45 rows\nconstant terms"),  # 3 x 4, 3 legend rows
        (3, 60.0, COEFFICIENTS, "t"),  # wide panel titles: 'chi2 = 5.37e+04 / 10, p = 0'
        (1, 1.0, COEFFICIENTS[:3], "one row of panels"),
    ],
)
def test_panel_titles_clear_the_panels_above_and_beside(n_runs, scatter, names, title):
    """Measured on the figure's renderer: a title of the second row stood on the x labels of the
    first, and titles ran into each other and into the figure title."""
    rows = campaign_rows(n_runs=n_runs, rng=np.random.default_rng(3), scatter=scatter)
    fig = compare_figure(rows, Variable.STATIC_ECCENTRICITY, list(names), title=title)
    assert _overlaps(fig) == []


def _predicted_lines(ax) -> list[tuple[str, list[tuple[float, float]]]]:
    return [
        (str(a.get_label()), [(x, pytest.approx(y)) for x, y in zip(a.get_xdata(), a.get_ydata())])
        for a in ax.get_lines()
        if str(a.get_label()).startswith("predicted")
    ]


def test_only_predictions_of_the_plotted_conditions_are_drawn(tmp_path):
    """The rows are at 1000 rpm, 0.4826 MPa, pressure ratio 0.25 (and 0.4 for a fourth run):
    a prediction line for another spin or pressure ratio is left out, a missing condition
    agrees with any, one dashed line per remaining set of conditions."""
    csv_file = tmp_path / "pred.csv"
    csv_file.write_text(
        "spin_rpm,recess_pressure_mpa,pressure_ratio,static_eccentricity,Kxx [N/m]\n"
        "1000,0.4826,0.25,0.0,2.0e7\n1000,0.4826,0.25,0.2,1.9e7\n"
        "1000,0.4826,0.4,0.0,3.3e7\n1000,0.4826,0.4,0.2,3.2e7\n"
        "2000,0.4826,0.25,0.0,5.0e7\n1000,0.6,0.25,0.0,6.0e7\n"
        ",,,0.1,1.5e7\n"
    )
    table = read_predicted(csv_file, Variable.STATIC_ECCENTRICITY)
    rows = campaign_rows()
    fig = compare_figure(rows, Variable.STATIC_ECCENTRICITY, ["Kxx"], title="t", predicted=table)
    assert _predicted_lines(fig.axes[0]) == [
        ("predicted", [(0.0, 20.0), (0.2, 19.0)]),  # MN/m
        ("predicted", [(0.1, 15.0)]),
    ]
    other = campaign_rows(n_runs=1)
    for row in other:
        row.update(run_id="rigA@2026-11-30T10:00:00+00:00", pressure_ratio=0.4)
    fig = compare_figure(rows + other, Variable.STATIC_ECCENTRICITY, ["Kxx"], title="t", predicted=table)
    assert _predicted_lines(fig.axes[0]) == [
        ("predicted, \u03b2 = 0.25", [(0.0, 20.0), (0.2, 19.0)]),
        ("predicted, \u03b2 = 0.4", [(0.0, 33.0), (0.2, 32.0)]),
        ("predicted", [(0.1, 15.0)]),
    ]


def test_predicted_csv_errors_name_the_line_of_the_file(tmp_path):
    """Comments count as lines; a header below comments is named by its own line; Excel's
    "CSV UTF-8" (a byte order mark first) is read."""
    bad_header = tmp_path / "h.csv"
    bad_header.write_text("# code A\n# 1000 rpm\nstatic_eccentricity,Kxx [MN/m]\n0.1,3e7\n")
    with pytest.raises(PredictedError, match=r"h.csv, line 3, column 'Kxx \[MN/m\]'"):
        read_predicted(bad_header)
    bad_cell = tmp_path / "c.csv"
    bad_cell.write_text("# code A\nstatic_eccentricity,Kxx [N/m]\n# from here at 1000 rpm\n0.1,3e7\n0.2,abc\n")
    with pytest.raises(PredictedError, match=r"c.csv, line 5, column 'Kxx': 'abc'"):
        read_predicted(bad_cell)
    bad_count = tmp_path / "n.csv"
    bad_count.write_text("# code A\nstatic_eccentricity,Kxx [N/m]\n0.1,3e7,9\n")
    with pytest.raises(PredictedError, match=r"n.csv, line 3: 3 cells for 2 columns"):
        read_predicted(bad_count)
    no_variable = tmp_path / "v.csv"
    no_variable.write_text("# code A\nKxx [N/m]\n3e7\n")
    with pytest.raises(PredictedError, match=r"v.csv, line 2: no column 'spin_rpm'"):
        read_predicted(no_variable, Variable.SPIN)
    excel = tmp_path / "excel.csv"
    excel.write_bytes("static_eccentricity,Kxx [N/m]\r\n0.1,3e7\r\n".encode("utf-8-sig"))
    assert read_predicted(excel, Variable.STATIC_ECCENTRICITY) == [{"static_eccentricity": 0.1, "Kxx": 3e7}]


def test_runs_of_one_calibration_record_are_compared_by_their_statistical_error():
    """The calibration part of U is common to runs of one record: u is the fit's standard
    error there (chi2 2 on 1 dof here, not 0.02 with u = U/2 = 10); runs of two records keep
    u = U/k (k = 2: these rows store none). The panel title says which."""
    import json

    from orbitrig.catalog.compare import UBasis

    rows = campaign_rows(n_runs=2)[:1] + campaign_rows(n_runs=2)[len(ECCENTRICITIES) :][:1]
    for row, value in zip(rows, (1.0, 3.0)):
        row.update(Kxx=value, Kxx_U=20.0, calibration_record_sha256="ab" * 32)
        row["coefficients_json"] = json.dumps({"values": {"Kxx": value}, "std": {"Kxx": 1.0}})
    rep = repeatability(rows, "Kxx")
    assert (rep.chi2, rep.dof, rep.basis) == (pytest.approx(2.0), 1, UBasis.STATISTICAL)
    assert rep.p_value == pytest.approx(chi2.sf(2.0, 1))
    assert rep.text() == f"repeats: \u03c7\u00b2 = 2 / 1\np = {chi2.sf(2.0, 1):.2g}, u = std. error"
    rows[1]["calibration_record_sha256"] = "cd" * 32  # another record: its calibration error differs
    rep = repeatability(rows, "Kxx")
    assert (rep.chi2, rep.basis) == (pytest.approx(0.02), UBasis.EXPANDED)
    assert rep.text().endswith(", u = U/k")
    fig = compare_figure(rows, Variable.STATIC_ECCENTRICITY, ["Kxx"], title="t")
    assert repeats_text(fig.axes[0]).get_text() == rep.text()  # under the panel's title


def test_compare_says_when_no_prediction_is_of_the_plotted_conditions(tmp_path):
    Catalog(f"sqlite:///{tmp_path / 'catalog.sqlite'}").add(campaign_rows())
    other = tmp_path / "p.csv"
    other.write_text("spin_rpm,static_eccentricity,Kxx [N/m]\n2000,0.1,5e7\n")
    res = CliRunner().invoke(
        app, ["compare", "--runs", str(tmp_path), "--predicted", str(other), "--out", str(tmp_path / "fig")]
    )
    assert (
        res.exit_code == 0 and f"--predicted {other}: no line's conditions are those of the plotted rows" in res.output
    )


def test_no_rows_says_what_the_catalog_holds(tmp_path):
    """A filter that matches nothing names the values its columns have among the fit kind's rows
    (the documented example once asked for pressure ratio 0.25 of runs at 0.4); a fit kind that
    is not there names the fit kinds that are."""
    Catalog(f"sqlite:///{tmp_path / 'catalog.sqlite'}").add(campaign_rows(n_runs=2))
    runner = CliRunner()
    base = ["compare", "--runs", str(tmp_path), "--out", str(tmp_path / "x")]
    res = runner.invoke(app, [*base, "--where", "pressure_ratio = 0.4 and static_eccentricity>=0.1"])
    assert res.exit_code == 2 and not (tmp_path / "x").exists()
    assert res.output.strip() == (
        "orbitrig compare: error: no catalog rows for piezo kcd11 none ols where pressure_ratio = 0.4 and static_eccentricity>=0.1; "
        "the catalog's 10 rows of that fit kind have pressure_ratio 0.25; static_eccentricity 0, 0.1, 0.2, 0.3, 0.4"
    )
    res = runner.invoke(app, [*base, "--model", "kc8", "--where", "pressure_ratio = 0.25"])
    assert res.exit_code == 2
    assert res.output.strip() == (
        "orbitrig compare: error: no catalog rows for piezo kc8 none ols where pressure_ratio = 0.25; "
        "the catalog's fits: piezo kcd11 none ols"
    )


def test_a_repeat_without_u_is_left_out_of_chi2_and_the_line_says_so():
    rows = campaign_rows(n_runs=3)
    first = [r for r in rows if r["point"] == 0]  # three runs at one eccentricity: one group
    for r, (x, u) in zip(first, [(1.0, 2.0), (3.0, 2.0), (50.0, None)]):
        r.update(Kxx=x, Kxx_U=u)  # the third has no U (and no standard error): no u
    rep = repeatability(first, "Kxx")
    assert (rep.chi2, rep.dof, rep.groups, rep.left_out) == (pytest.approx(2.0), 1, 1, 1)
    assert rep.text() == f"repeats: \u03c7\u00b2 = 2 / 1\np = {chi2.sf(2.0, 1):.2g}, u = U/k; 1 without U left out"
    assert repeatability(first[:2], "Kxx").text().endswith("u = U/k")  # none left out: not said


def test_repeats_far_outside_their_u_say_p_below_the_floor_not_p_0():
    """chi2 = 2e6 on 1 dof: its upper tail underflows to 0, which the line must not call
    "p = 0" (an impossible result) but "p < 1e-300" as every p the rig prints."""
    rows = campaign_rows(n_runs=2)[:1] + campaign_rows(n_runs=2)[len(ECCENTRICITIES) :][:1]
    rows[0].update(Kxx=0.0, Kxx_U=2.0)
    rows[1].update(Kxx=2000.0, Kxx_U=2.0)  # u = 1 each: mean 1000, chi2 = 2 * 1000^2
    rep = repeatability(rows, "Kxx")
    assert (rep.chi2, rep.p_value) == (pytest.approx(2e6), 0.0)
    assert rep.text() == "repeats: \u03c7\u00b2 = 2e+06 / 1\np < 1e-300, u = U/k"
