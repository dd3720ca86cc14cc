"""The report's coherence table, truth markers, derived quantities, impedance against the
truth, and the identify-v2 items of the page (intervals, budget, adequacy, warnings), checked
for content: the drawn data and the rendered pixels against the stored numbers and the
synthetic truth."""

from __future__ import annotations

import copy
import dataclasses
import re

import numpy as np
import pytest
from matplotlib.colors import to_rgb

from orbitrig.analysis.plots import Fitted
from orbitrig.analysis.plot_marks import keep_inside
from orbitrig.analysis.plots_coefficients import POINT_TRUTH_LABEL, coefficients_figure
from orbitrig.analysis.plots_coherence import BANDS, band_colour, coherence_figure, coherence_table
from orbitrig.analysis.plots_derived import c_eff, derived_figure, impedance_figure
from orbitrig.analysis.quality import adequacy_verdicts, derived_of, true_impedance
from orbitrig.analysis.report_analysis import analyse_point, fit_label
from orbitrig.analysis.report_tables import identification_table, verdict_list
from orbitrig.analysis.rounding import uncertainty_decimals
from orbitrig.store.reader import read_run
from reduction.systematic import UncertaintyBasis
from support.report_synthetic import C_TRUE, D_TRUE, K_TRUE


@pytest.fixture(scope="module")
def point_report(synthetic_run):
    return analyse_point(read_run(synthetic_run).points[1])


def _pixel(fig, ax, x, y) -> tuple[float, float, float]:
    """RGB (0..1) of the rendered figure at data point (x, y) of `ax`."""
    fig.canvas.draw()
    rgba = np.asarray(fig.canvas.buffer_rgba())
    px, py = ax.transData.transform((x, y))
    return tuple(rgba[int(round(rgba.shape[0] - py)), int(round(px)), :3] / 255.0)


def test_coherence_is_a_coloured_table_of_the_stored_values(point_report):
    point = point_report.point
    table = coherence_table(point.tables)
    assert table.lms == ["piezo", "strain"] and table.values.shape == (20, 8)
    assert table.rows[0] == "0.200 fwd" and table.rows[-1] == "1.200 bwd"
    piezo = point.tables["piezo"]
    first_bwd = int(
        np.flatnonzero(
            (piezo.orbit / piezo.spin > 0.19)
            & (piezo.orbit / piezo.spin < 0.21)
            & (np.imag(np.conj(piezo.x) * piezo.y) > 0)
        )[0]
    )
    np.testing.assert_array_equal(table.values[10, :4], piezo.gamma2[first_bwd])
    fig = coherence_figure(table, title="t")
    ax = fig.axes[0]
    texts = [t.get_text() for t in ax.texts]
    assert texts == [f"{v:.3f}" for v in table.values.ravel()]
    # the rendered cell colour (left of the number) is its band's colour
    for r, c in ((0, 0), (7, 5), (19, 3), (12, 7)):
        got = _pixel(fig, ax, c - 0.4, r)
        assert np.allclose(got, to_rgb(band_colour(table.values[r, c])), atol=0.02), (r, c, got)


def test_band_colours():
    assert band_colour(0.995) == BANDS[0][1] and band_colour(0.96) == BANDS[1][1]
    assert band_colour(0.91) == BANDS[2][1] and band_colour(0.5) == BANDS[3][1]
    assert band_colour(float("nan")) == "#cccccc"
    assert band_colour(0.9896) == BANDS[0][1]  # reads 0.990: coloured as it reads


def test_truth_markers_stay_inside_the_axes_even_far_from_the_fit(point_report):
    point = point_report.point
    r = point_report.results["piezo"][1]
    truth = copy.deepcopy(point.truth)
    truth["K"] = (np.asarray(truth["K"]) * 3).tolist()  # far outside what the fit draws
    t = point.tables["piezo"]
    fig = coefficients_figure(
        [Fitted(fit_label(r), r.identification)], spin=t.spin, orbit=t.orbit, truth=truth, title="t"
    )
    crosses = 0
    for ax in fig.axes:
        for line in ax.get_lines():
            if line.get_label() != POINT_TRUTH_LABEL:  # no fit carries its own truth here
                continue
            (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
            x, y = np.asarray(line.get_xdata()), np.asarray(line.get_ydata())
            assert np.all((x > x0) & (x < x1) & (y > y0) & (y < y1)), ax.get_title()
            crosses += x.size
    assert crosses == 12 * 20  # K, C, D entries at 20 orbit frequencies


def test_keep_inside_widens_only_when_needed():
    from orbitrig.analysis.plots import report_figure

    ax = report_figure(3, 3).add_subplot()
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    keep_inside(ax, [0.5], [0.5])
    assert ax.get_xlim() == (0, 1) and ax.get_ylim() == (0, 1)
    keep_inside(ax, [2.0], [-1.0])
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    assert x0 == 0 and x1 > 2.0 and y0 < -1.0 and y1 == 1


def test_derived_quantities_drawn_and_near_the_hand_values(point_report):
    """Constant true coefficients: C_eff,xx = Cxx - Kxy/Omega is zero at Kxy/Cxx, C_eff,yy at -Kyx/Cyy."""
    t = point_report.point.tables["piezo"]
    r = next(r for r in point_report.results["piezo"] if (r.model, r.freq_dep) == ("kcd11", "none"))
    d = derived_of(r, t.orbit)
    w0_xx, w0_yy = K_TRUE[0, 1] / C_TRUE[0, 0], -K_TRUE[1, 0] / C_TRUE[1, 1]
    assert d.c_eff_zero_xx[0] == pytest.approx(w0_xx, rel=0.02)
    assert d.c_eff_zero_yy[0] == pytest.approx(w0_yy, rel=0.02)
    fig = derived_figure([(fit_label(r), d, UncertaintyBasis.STATISTICAL)], spin=t.spin, title="t")
    ceff_xx, _, wfr = fig.axes[:3]
    np.testing.assert_allclose(ceff_xx.get_lines()[0].get_ydata(), d.c_eff_xx * 1e-3)
    np.testing.assert_allclose(ceff_xx.get_lines()[0].get_xdata(), d.orbit / t.spin)
    (entry,) = (t.get_text() for t in fig.legends[0].get_texts())
    assert c_eff("xx") in ceff_xx.get_title()  # the panel the legend's C_eff,xx names
    assert entry.startswith(f"{fit_label(r)}: {c_eff('xx')} = 0 at ")
    hz = float(
        re.search(
            r"eff,xx\}\$ = 0 at ([\d.]+)\u00a0\u00b1\u00a0[\d.]+\u00a0Hz, \u03a9/\u03c9\u00a0[\d.]{5}; C", entry
        ).group(1)
    )
    assert hz == pytest.approx(w0_xx / (2 * np.pi), rel=0.02)
    wfr_true = (K_TRUE[0, 1] - K_TRUE[1, 0]) / (t.spin * (C_TRUE[0, 0] + C_TRUE[1, 1]))
    assert wfr.get_lines()[0].get_ydata() == pytest.approx(wfr_true, rel=0.02)
    re_h = fig.axes[3].get_lines()[0].get_ydata() * 1e6  # forward H, N/m
    z = K_TRUE[None] + 1j * d.orbit[:, None, None] * C_TRUE - d.orbit[:, None, None] ** 2 * D_TRUE
    h_true = (z[:, 0, 0] + z[:, 1, 1]) / 2 + 1j * (z[:, 1, 0] - z[:, 0, 1]) / 2
    np.testing.assert_allclose(re_h, h_true.real, rtol=0.01)


def test_impedance_against_the_stored_true_z(point_report):
    point, t = point_report.point, point_report.point.tables["piezo"]
    fitted = [Fitted(fit_label(r), r.identification) for r in point_report.results["piezo"]]
    reference = true_impedance(point.truth)  # from the truth's K, C, D rows
    w = reference.orbit
    expect = K_TRUE[None] + 1j * w[:, None, None] * C_TRUE - w[:, None, None] ** 2 * D_TRUE
    np.testing.assert_allclose(reference.z, expect)
    assert not reference.exact and reference.label == "simulator's K, C, D (reference fit)"
    stored = dict(point.truth, Z_re=(expect.real * 1.1).tolist(), Z_im=expect.imag.tolist())
    true = true_impedance(stored)  # a stored true Z per frequency wins
    assert true.exact and true.label == "true Z (simulator)"
    z2 = true.z
    np.testing.assert_allclose(z2.real, expect.real * 1.1)
    fig = impedance_figure(fitted, true, spin=t.spin, orbit=t.orbit, title="t")
    re_xy = fig.axes[1]
    cross = next(ln for ln in re_xy.get_lines() if ln.get_label() == "true Z (simulator)")
    np.testing.assert_allclose(cross.get_ydata(), z2[:, 0, 1].real * 1e-6)
    model = re_xy.get_lines()[0]
    grid = model.get_xdata() * t.spin
    np.testing.assert_allclose(model.get_ydata(), fitted[0].identification.impedance(grid)[:, 0, 1].real * 1e-6)
    (y0, y1) = re_xy.get_ylim()
    assert np.all((cross.get_ydata() > y0) & (cross.get_ydata() < y1))


def test_impedance_bands_show_each_fits_expanded_uncertainty(point_report):
    """Each identified Re Z and Im Z carries its band of U = k u, u from the fit's covariance
    (Re Z = K - Omega^2 D, Im Z = Omega C: the entries' gradients), and the legend says so; a
    reviewer judges a cross of the truth against it. Without bands the figure showed no
    uncertainty at all."""
    from orbitrig.analysis.plots import coverage
    from reduction.derived import entry_gradient

    t = point_report.point.tables["piezo"]
    fitted = [Fitted(fit_label(r), r.identification) for r in point_report.results["piezo"]]
    truth = true_impedance(point_report.point.truth)
    fig = impedance_figure(fitted, truth, spin=t.spin, orbit=t.orbit, title="t")
    legend = fig.legends[0].get_title().get_text()
    assert "bands: \u00b1expanded uncertainty U (k = 2), statistical" in legend
    # the legend says what is drawn: the tested range only, no dotted extrapolation it would name
    assert "over the tested range (no extrapolation drawn)" in legend and "dotted" not in legend
    assert not [ln for ax in fig.axes for ln in ax.get_lines() if ln.get_linestyle() == ":"]
    for col, e in enumerate(("xx", "xy", "yx", "yy")):
        for row in (0, 1):
            ax = fig.axes[row * 4 + col]
            polys = [c for c in ax.collections if c.get_paths()]
            assert len(polys) == len(fitted)  # one band per fit
            for fit, poly in zip(fitted, polys):
                ident = fit.identification
                verts = poly.get_paths()[0].vertices
                n = len(verts) // 2
                w = verts[:n, 0] * t.spin
                g = {m: entry_gradient(ident, m, e, w) for m in "KCD"}
                grad = g["K"] - w[:, None] ** 2 * g["D"] if row == 0 else w[:, None] * g["C"]
                u = np.sqrt(np.einsum("kp,pq,kq->k", grad, ident.covariance, grad)) * 1e-6
                half = (verts[n : 2 * n, 1][::-1] - verts[:n, 1]) / 2
                np.testing.assert_allclose(half, coverage() * u, rtol=1e-9, atol=1e-12)
                z = ident.impedance(w)[:, *divmod(col, 2)]
                centre = (z.real if row == 0 else z.imag) * 1e-6
                np.testing.assert_allclose((verts[n : 2 * n, 1][::-1] + verts[:n, 1]) / 2, centre, rtol=1e-9)


def test_adequacy_verdict_for_constant_truth(point_report):
    verdicts = adequacy_verdicts("piezo", point_report.results["piezo"])
    assert [(v.dependent.model, v.dependent.freq_dep) for v in verdicts] == [("kcd11", "power:1")]
    v = verdicts[0]
    # the synthetic tables carry u_* (known noise): the likelihood-ratio test; the truth is constant
    assert v.adequacy.test == "likelihood ratio" and not v.adequacy.supported
    assert v.text == f"frequency dependence supported: no (p = {v.adequacy.p_value:.3g})"
    html = verdict_list(verdicts, {id(v.dependent): "kcd11 power:1 (22 coef.)"})
    assert "kcd11 power:1 (22 coef.)</b>: frequency dependence supported: no (p = " in html
    assert f"AIC {v.adequacy.aic[0]:.5g} (constant)" in html
    # the statistic on its degrees of freedom and the level: the p can be checked from the page
    a, dep = v.adequacy, v.dependent.identification
    assert a.dof[0] == 11  # 22 - 11 coefficients added
    assert f"constant fit \u2212 \u03c7\u00b2 of this one = {a.statistic:.4g} on 11 degrees of freedom" in html
    assert "dof 11/0" not in html and "supported when p &lt; 5 %" in html
    assert (
        f"this fit alone: \u03c7\u00b2 = {dep.chi2:.4g} on {dep.dof} degrees of freedom (p = {dep.p_value:.3g})" in html
    )
    f_test = dataclasses.replace(v, adequacy=dataclasses.replace(a, test="F", statistic=3.25, dof=(11, 29)))
    assert "F test: F = 3.25 on (11, 29) degrees of freedom" in verdict_list([f_test], {})
    underflowed = dataclasses.replace(v.dependent, identification=dataclasses.replace(dep, p_value=0.0))
    html = verdict_list([dataclasses.replace(v, dependent=underflowed)], {})
    assert f"this fit alone: \u03c7\u00b2 = {dep.chi2:.4g} on {dep.dof} degrees of freedom (p &lt; 1e-300)" in html


def test_identification_table_shows_interval_budget_warnings(point_report):
    r = copy.copy(next(r for r in point_report.results["piezo"] if r.freq_dep == "none" and r.model == "kcd11"))
    ident = r.identification
    html = identification_table(r, {}, "kcd11", with_budget=False)
    lo, hi = ident.confidence_95["Kxy"]
    places = uncertainty_decimals(ident.std_errors["Kxy"] * 1e-6)  # the std error's decimal (test_report_rounding)
    assert f"[{lo * 1e-6:.{places}f}, {hi * 1e-6:.{places}f}]" in html
    assert f"{ident.aic:.5g} / {ident.bic:.5g}" in html and f'<td colspan="4" class="l">{ident.dof}</td>' in html
    r.stored = dict(
        {k: v for k, v in (r.stored or {}).items() if k != "expanded_uncertainty"},  # the budget's U alone
        warnings=["Cxy is ill-conditioned"],
        uncertainty={"k": 2.0, "systematic": {"Kxy": 12345.0}, "expanded": {"Kxy": 67890.0}},
    )
    html = identification_table(r, {}, "kcd11", with_budget=True)
    assert "warning: Cxy is ill-conditioned" in html
    assert "expanded U<br>(combined, 95.45 %)" in html and "k<br>(of U)" in html
    # a run stored before U's k per coefficient: its one k on every row
    assert f"<td>{12345.0 * 1e-6:.2g}</td><td>{67890.0 * 1e-6:.2g}</td><td>2</td>" in html
    # the sweep's combined U: each coefficient's own k (Student's t at its effective dof)
    r.stored["uncertainty"] = dict(r.stored["uncertainty"], k=3.31, k_values={"Kxx": 2.0, "Kxy": 3.31})
    html = identification_table(r, {}, "kcd11", with_budget=True)
    assert f"<td>{12345.0 * 1e-6:.2g}</td><td>{67890.0 * 1e-6:.2g}</td><td>3.31</td>" in html


def test_page_shows_verdict_beside_figure_5_and_derived_table(synthetic_run, synthetic_report):
    assert synthetic_report.exit_code == 0, synthetic_report.output
    html = synthetic_report.page
    side = re.search(r'<div class="side">(.*?)</div></div>', html, re.S).group(1)
    assert 'src="forces_0001_piezo.png"' in side and "frequency dependence supported: no (p = " in side
    assert (
        "WFR at 3.333 Hz" in html and "C<sub>eff,xx</sub> = C<sub>xx</sub> \u2212 K<sub>xy</sub>/\u03a9 = 0 at" in html
    )
    assert "95 % interval" in html and "AIC / BIC" in html
    assert "Systematic (calibration) uncertainty: not stored in this run" in html


def test_every_figure_caption_says_what_it_shows_and_what_its_bars_are(synthetic_report):
    """A reader of the page learns from each caption what the figure shows and that its bands and
    error bars are U (k and basis in the legend); a figure without bars (coherence, orbits,
    signals) does not claim any. Every figure of the page has its kind's caption."""
    from orbitrig.analysis.report_html import BARS_CAPTION, FIGURE_CAPTIONS

    captions = dict(re.findall(r'<img src="([^"]+)\.png".*?<figcaption>(.*?)</figcaption>', synthetic_report.page))
    assert {"forces_0001_piezo", "coefficients_0001_piezo_kcd11", "coherence_0001"} <= set(captions)
    for stem, caption in captions.items():
        kind = stem.split("_")[0]
        assert caption.startswith(FIGURE_CAPTIONS[kind] + "."), stem
        assert (BARS_CAPTION in caption) == (kind not in {"coherence", "orbits", "signals"}), stem
        assert caption.endswith(f'<span class="muted">{stem}.png (full size: click)</span>')
    assert "(paper Figs. 6 and 7)" in captions["coefficients_0001_piezo_kcd11"]
    assert "\u00b1 the expanded uncertainty U = k u" in captions["forces_0001_piezo"]


def test_the_coherence_table_says_how_many_revolutions_each_estimate_rests_on(synthetic_run, synthetic_report):
    """gamma^2 of one record is 1 whatever the noise: the page says the number of records behind
    each row, as the stored orbit tables hold it."""
    tables = read_run(synthetic_run).points[1].tables
    counts = {int(n) for t in tables.values() for n in t.n_records}
    note = re.search(r"Coherence between motion and force signals</h4>.*?</p>", synthetic_report.page, re.S).group(0)
    n = f"{min(counts)}" if len(counts) == 1 else f"{min(counts)} to {max(counts)}"
    assert f"Each \u03b3\u00b2 from the {n} revolutions (records) averaged at its orbit frequency." in note


def test_each_fit_gives_its_birge_ratio_and_says_when_its_std_errors_understate(point_report):
    """sqrt(chi2 / (4n - p)): about 1 when the residuals scatter as the stated u_* say; where the
    chi2 test rejects the fit the row says the std errors and U take u_* as stated."""
    import math

    r = next(r for r in point_report.results["piezo"] if r.freq_dep == "none" and r.model == "kcd11")
    ident = r.identification
    html = identification_table(r, {}, "kcd11", with_budget=False)
    ratio = math.sqrt(ident.chi2 / ident.dof)
    row = re.search(r"Birge ratio \u221a\(\u03c7\u00b2/\(4n \u2212 p\)\)</th><td[^>]*>([^<]*)", html).group(1)
    assert row == f"{ratio:.3g}" and ident.p_value >= 1e-3  # the synthetic fit agrees with its u_*
    rejected = copy.copy(r)
    rejected.identification = dataclasses.replace(ident, chi2=100.0 * ident.dof, p_value=0.0)
    html = identification_table(rejected, {}, "kcd11", with_budget=False)
    assert "10: the residuals scatter 10 times what the stated u<sub>*</sub> give; the std errors and U" in html
    # a p that underflowed, escaped for the page: "p &lt; 1e-300"
    assert f"{100.0 * ident.dof:.4g} (p &lt; 1e-300)</td>" in html and "(p < 1e-300)" not in html


def test_page_names_coefficients_subscripted_and_the_csv_by_their_keys(synthetic_run, synthetic_report):
    """The page's tables write K<sub>xx</sub> (K<sub>xx,1</sub>: the Omega^1 term), never Kxx; the
    CSV a program reads keeps the plain keys."""
    html = synthetic_report.page
    assert '<th class="l">K<sub>xx</sub></th>' in html and '<th class="l">K<sub>xx,1</sub></th>' in html
    assert re.findall(r">[KCD](?:xx|xy|yx|yy)(?:_\d+)?\b", html) == []
    header = (synthetic_run / "coefficients.csv").read_text(encoding="utf-8").splitlines()[0].split(",")
    assert {"Kxx [N/m]", "Cyx [N s/m]", "Dxy [kg]"} <= set(header)


def test_fit_warnings_name_point_model_and_text(synthetic_run):
    pr = analyse_point(read_run(synthetic_run).points[0])
    r = pr.results["piezo"][0]
    r.stored = dict(r.stored or {}, warnings=["ill-conditioned: Kxy, Cxx poorly determined"])
    lines = pr.fit_warnings()
    assert f"piezo {r.model} {r.freq_dep} warns: ill-conditioned: Kxy, Cxx poorly determined" in lines
    assert any(line.startswith("piezo kcd12 poly:8 refused: ") for line in lines)


def test_lms_consistency_table_shows_the_normalised_difference(point_report):
    """The strain gauges read 1.8 % high (synthetic): the K entries differ by about 1.8 %, and
    E_n = (piezo - strain) / u is negative and large where the statistical uncertainty is small."""
    from orbitrig.analysis.quality import LmsComparison, lms_normalised_difference
    from orbitrig.analysis.report_analysis import preferred
    from orbitrig.analysis.report_tables import consistency_table

    found = preferred(point_report)
    a, b = found["piezo"], found["strain"]
    ag = lms_normalised_difference(a, b)
    en = ag.e_n
    ka, kb = a.identification.coefficients["Kxx"], b.identification.coefficients["Kxx"]
    assert 100 * (kb - ka) / ka == pytest.approx(1.8, abs=0.3)
    u = np.hypot(a.identification.std_errors["Kxx"], b.identification.std_errors["Kxx"])
    assert en["Kxx"] == pytest.approx((ka - kb) / u, rel=1e-6) and en["Kxx"] < -2
    html = consistency_table(a, b, LmsComparison(ag, UncertaintyBasis.STATISTICAL, stored=False), "kcd11 (11 coef.)")
    # 1.8 % on every coefficient: far beyond the joint limit, and Kxx beyond the per-coefficient mark
    assert not ag.consistent and ag.dof == 11 and ag.chi2 > ag.limit and "NOT consistent" in html
    assert abs(en["Kxx"]) > ag.e_n_limit() > 2
    assert f'<td class="err">{en["Kxx"]:+.2f}</td>' in html
    # the relative difference has E_n's sign: (piezo - strain) / |piezo|, negative here as E_n
    assert f"<td>{100 * (ka - kb) / abs(ka):+.2f}</td>" in html and (ka - kb) < 0
    assert "<th>(piezo \u2212 strain) / |piezo| [%]</th>" in html
    nd = set(a.stored["not_determined"]) | set(b.stored["not_determined"])  # the cross-coupled D's here
    assert "Kxx" not in nd and html.count("<td>n.d.</td>") == len(nd) > 0
    # a coefficient not determined by either fit (U exceeds the value): no relative difference, E_n kept
    strain_nd = dataclasses.replace(b, stored={**(b.stored or {}), "not_determined": ["Kxx"]})
    html = consistency_table(a, strain_nd, LmsComparison(ag, UncertaintyBasis.STATISTICAL, stored=False), "kcd11")
    (kxx,) = [row for row in html.split("</tr>") if "K<sub>xx</sub>" in row]
    assert f"<td>{100 * (ka - kb) / abs(ka):+.2f}</td>" not in kxx and "<td>n.d.</td>" in kxx
    assert f'<td class="err">{en["Kxx"]:+.2f}</td>' in kxx and "n.d.: not determined by one of the two" in html


def test_figure_5_error_bars_from_the_phasor_uncertainty(point_report):
    """With u_* in the table the measured amplitudes carry the expanded uncertainty U = 2 u
    (radial part U / sqrt(2) of an isotropic complex error) and the residual panels show U per
    frequency; without u_*, neither."""
    from matplotlib.container import ErrorbarContainer

    from orbitrig.analysis import plots_forces
    from reduction.table import OrbitTable

    stored = point_report.point.tables["piezo"]
    t = OrbitTable(stored.spin, stored.orbit, stored.x, stored.y, stored.fx, stored.fy, gamma2=stored.gamma2)
    u = np.column_stack([np.full(t.orbit.size, 1e-8)] * 2 + [0.01 * np.abs(t.fx), 0.02 * np.abs(t.fy)])
    with_u = OrbitTable(t.spin, t.orbit, t.x, t.y, t.fx, t.fy, gamma2=t.gamma2, n_records=np.full(t.orbit.size, 8), u=u)
    fitted = [Fitted("kc7", point_report.results["piezo"][0].identification)]
    fig = plots_forces.forces_figure(with_u, fitted, title="t")  # a figure is valid until the next of its shape
    amp_fy, residual_fy = fig.axes[1], fig.axes[3]
    bars = [c for c in amp_fy.containers if isinstance(c, ErrorbarContainer)]
    assert len(bars) == 2  # forward and backward
    half = np.concatenate([[abs(s[1][1] - s[0][1]) / 2 for s in c.lines[2][0].get_segments()] for c in bars])
    # u_fy = 0.02 |Fy|: amplitude bars 2 * 0.02 |Fy| / sqrt(2); residual panel: U = 2 * 0.02 |Fy|
    assert np.sort(half) == pytest.approx(np.sort(2 * 0.02 * np.abs(t.fy) / np.sqrt(2)))
    shown = np.concatenate([ln.get_ydata() for ln in residual_fy.get_lines() if ln.get_gid() == "measured-uncertainty"])
    assert np.sort(shown) == pytest.approx(np.sort(2 * 0.02 * np.abs(t.fy)))
    fig = plots_forces.forces_figure(t, fitted, title="t")  # the same figure, emptied: no bar of the last one left
    assert not any(isinstance(c, ErrorbarContainer) for ax in fig.axes for c in ax.containers)
    assert not any(ln.get_gid() == "measured-uncertainty" for ax in fig.axes for ln in ax.get_lines())


def test_identification_table_shows_the_fits_own_truth_and_not_determined(point_report):
    r = copy.copy(next(r for r in point_report.results["piezo"] if r.freq_dep == "none" and r.model == "kcd11"))
    own = {k: 2.0 * v for k, v in r.identification.coefficients.items()}
    r.stored = dict(r.stored or {}, not_determined=["Dxy", "Dyx"], truth={"coefficients": own, "definition": "x"})
    html = identification_table(r, {"Kxx": 1.0}, "kcd11", with_budget=False)
    assert "true (simulator, this model)" in html
    std = r.identification.std_errors
    kyy = f"{own['Kyy'] * 1e-6:.{uncertainty_decimals(std['Kyy'] * 1e-6)}f}"
    assert f"<td>{kyy}</td></tr>" in html  # the fit's own truth, not the constant one given
    dxy = f"{r.identification.coefficients['Dxy']:.{uncertainty_decimals(std['Dxy'])}f}"
    assert f"<td>{dxy} <b>n.d.</b></td>" in html and html.count("<b>n.d.</b>") == 2
    assert "n.d. = not determined" in html and "D is an apparent inertia (added mass)" in html
