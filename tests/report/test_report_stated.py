"""The report page says what the stored run says: the two load measuring systems' consistency
on the sweep's own uncertainty basis (combined when the rig stated a calibration uncertainty;
written and read as one Enum, stored as its text), and each 95 % interval named by the kind its
identification used (normal with u_*, else Student t; one sentence when nothing was identified)."""

from __future__ import annotations

import re

import numpy as np
import pytest

from orbitrig import config as cfg
from orbitrig.analysis.quality import lms_comparison
from orbitrig.analysis.report import Report
from orbitrig.analysis.typeset import entry_html
from orbitrig.analysis.report_analysis import analyse_point, fit_label, preferred
from orbitrig.analysis.report_html import render
from orbitrig.analysis.report_tables import identification_table
from orbitrig.store.reader import read_run
from reduction.identify import identify
from reduction.methods import Method
from reduction.systematic import UncertaintyBasis
from reduction.table import OrbitTable
from support.report_synthetic import write_synthetic_run

#: force channels' gain uncertainty 1 %, phase 0.2 deg: the strain gauges' 1.8 % offset is within it
STATED = cfg.CalibrationUncertainty(
    probe_sensitivity_pct=0.5,
    **{f"f{a}_{lms}": cfg.ChannelUncertainty(gain_pct=1.0, phase_deg=0.2) for a in "xy" for lms in cfg.LMS},
)


def _page(directory) -> tuple[str, object]:
    """index.html of point 1 of the run in `directory` (no figures), and its PointReport."""
    run = read_run(directory)
    pr = analyse_point(run.points[1])
    return render(Report(run, directory / "plots", [pr])), pr


@pytest.fixture(scope="module")
def calibrated_run(tmp_path_factory):
    return write_synthetic_run(tmp_path_factory.mktemp("calibrated") / "run", incomplete=0, calibration=STATED)


def _consistency_paragraph(page: str) -> str:
    return re.search(r"consistency</h4>.*?</p>", page, re.S).group(0)


@pytest.mark.parametrize("calibrated", [True, False])
def test_consistency_is_the_stored_one_on_its_basis(calibrated, calibrated_run, synthetic_run):
    page, pr = _page(calibrated_run if calibrated else synthetic_run)
    a = preferred(pr)["piezo"]
    stored = a.stored["lms_consistency"]
    assert stored["basis"] == ("combined" if calibrated else "statistical")
    section = _consistency_paragraph(page)
    assert f"\u03c7\u00b2 = {stored['chi2']:.3g} on {stored['dof']} " in section  # typeset, as the quality rows
    verdict = (
        "All coefficients at once: " + ("consistent" if stored["consistent"] else "NOT consistent") + ", \u03c7\u00b2"
    )
    assert verdict in section
    assert "no calibration budget stored" not in section
    if calibrated:  # the budget the sweep used, and the sentence says so
        assert "combined uncertainties of both fits" in section and "calibration uncertainty" in section
        assert stored["consistent"]  # 1.8 % within 1 % per force channel: the stored verdict
    else:
        assert "statistical uncertainties of both fits" in section and "combined" not in section
    # every E_n of the table is the stored one
    for key, e in stored["e_n"].items():
        row = re.search(rf'<th class="l">{re.escape(entry_html(key))}</th>.*?</tr>', section, re.S).group(0)
        assert row.endswith(f">{e:+.2f}</td></tr>".replace("-", "\u2212")), (key, row)  # negative: the minus sign


@pytest.mark.parametrize("calibrated", [True, False])
def test_the_basis_is_written_and_read_as_one_enum(calibrated, calibrated_run, synthetic_run):
    """The sweep stores both bases as the text of reduction.systematic.UncertaintyBasis (the
    strings runs stored before it have), and the page reads the comparison's back as that Enum."""
    _, pr = _page(calibrated_run if calibrated else synthetic_run)
    a, b = preferred(pr)["piezo"], preferred(pr)["strain"]
    want = UncertaintyBasis.COMBINED if calibrated else UncertaintyBasis.STATISTICAL
    assert want.value == ("combined" if calibrated else "statistical")
    for stored in (a.stored["lms_consistency"]["basis"], a.stored["expanded_uncertainty"]["basis"]):
        assert type(stored) is str and stored == want.value
    assert lms_comparison(a, b).basis is want


def test_the_units_note_reads_as_one_sentence_without_identifications(synthetic_run):
    """Nothing identified: the interval clause ends the sentence (no stray period, no U claimed)."""
    page = render(Report(read_run(synthetic_run), synthetic_run / "plots", []))
    note = re.search(r"Units: .*?</p>", page, re.S).group(0)
    assert "95 % interval: none identified. Higher-order" in note and ".;" not in note
    assert "expanded U" not in note


@pytest.mark.parametrize("calibrated", [True, False])
def test_the_units_note_claims_a_combined_u_only_when_one_is_stored(calibrated, calibrated_run, synthetic_run):
    page, pr = _page(calibrated_run if calibrated else synthetic_run)
    note = re.search(r"Units: .*?</p>", page, re.S).group(0)
    stored = any((r.stored or {}).get("uncertainty") for rs in pr.results.values() for r in rs)
    assert stored is calibrated
    assert ("expanded U: k times the combined (statistical and systematic)" in note) is calibrated
    assert ("expanded U<br>(combined" in page) is calibrated  # the tables' column, likewise


def test_interval_named_by_the_identification_normal_with_u(synthetic_run):
    """The synthetic orbit tables state u_*: every fit uses the normal quantile 1.96."""
    page, pr = _page(synthetic_run)
    results = [r for rs in pr.results.values() for r in rs]
    assert results and {r.identification.interval for r in results} == {"normal"}
    r = results[0]
    std, (lo, hi) = r.identification.std_errors["Kxx"], r.identification.confidence_95["Kxx"]
    assert (hi - lo) / 2 / std == pytest.approx(1.96, abs=1e-3)
    assert "Student" not in page
    assert page.count("95 % interval, statistical only<br>(normal, 1.96)") == len(results)
    assert "95 % interval, statistical only (standard errors, no calibration uncertainty): normal quantile 1.96" in page


def test_interval_named_student_t_without_u(synthetic_run):
    pr = analyse_point(read_run(synthetic_run).points[1])
    r = pr.results["piezo"][0]
    t = r.point.tables["piezo"]
    r.identification = identify(
        OrbitTable(t.spin, t.orbit, t.x, t.y, t.fx, t.fy, gamma2=t.gamma2), model=r.model, freq_dep=r.freq_dep
    )
    assert r.identification.interval == "student_t"
    html = identification_table(r, {}, fit_label(r), with_budget=False)
    assert "95 % interval, statistical only<br>(Student t, 4n \u2212 p dof)" in html and "normal" not in html
    std, (lo, hi) = r.identification.std_errors["Kxx"], r.identification.confidence_95["Kxx"]
    assert (hi - lo) / 2 / std > 1.97 and np.isfinite(hi)


def test_each_table_heading_names_its_method_once(synthetic_run):
    """'kcd11 (11 coef.), wls', never 'kcd11 (11 coef.), wls (wls)'; ols named too."""
    run = read_run(synthetic_run)
    pr = analyse_point(run.points[1])
    r = pr.results["piezo"][0]
    r.method = Method.WLS
    r.identification = identify(r.point.tables["piezo"], model=r.model, freq_dep=r.freq_dep, method=Method.WLS)
    heads = re.findall(r"<h4>([^<]*coef\.[^<]*)</h4>", render(Report(run, synthetic_run / "plots", [pr])))
    results = [r for rs in pr.results.values() for r in rs]
    assert len(heads) == len(results) >= 2
    assert heads[0] == f"{r.model} ({r.identification.n_coefficients} coef.), wls" and heads[1].endswith(", ols")
    for head in heads:
        assert sum(head.count(m) for m in ("ols", "wls", "tls", "iv")) == 1


def test_the_units_note_states_the_sign_convention_of_the_coefficients(synthetic_run):
    """A journal's reader needs the sign the coefficients are stated in: the force on the journal,
    f = -(K d + C d' + D d'') = -Z d, positive along +x and +y, Kxy the force in x per displacement
    in y, that Omega > 0 whatever the whirl direction (the direction lies in the phasors; a
    frequency-dependent K(Omega) is the same for both; forward turns with the spin, from +x towards
    +y) and that a difference of the two systems is piezo - strain."""
    run = read_run(synthetic_run)
    page = render(Report(run, synthetic_run / "plots", []))
    note = re.search(r"Units: .*?</p>", page, re.S).group(0)
    assert (
        "Sign convention: f = \u2212(K d + C \u1e0b + D d\u0308) = \u2212Z d, Z(\u03a9) = K + i\u03a9C \u2212 \u03a9\u00b2D, "
        "f the fluid-film force on the journal, positive along +x and +y, d = (x, y) the journal&#x27;s displacement "
        "in the bearing (K<sub>xy</sub>: the force in x per displacement in y); \u03a9 &gt; 0 the orbit frequency, "
        "one Z for both whirl directions: the direction lies in the displacement phasors (forward whirl, with the "
        "spin from +x towards +y, y = \u2212i x; backward y = +i x); the two systems&#x27; difference is "
        "piezo \u2212 strain."
    ) in note
    assert "\u03a9 &lt; 0 backward" not in note and "|\u03a9|" not in note
    # as the stored tables hold it: both directions, every orbit frequency positive
    t = run.points[1].tables["piezo"]
    turn = np.sign(np.imag(np.conj(t.x) * t.y))
    assert (t.orbit > 0).all() and set(turn) == {-1.0, 1.0}
    assert np.allclose(t.y[turn < 0] / t.x[turn < 0], -1j, atol=0.1)  # forward: y = -i x


def test_the_units_note_names_the_uncertainty_types_and_coverage(calibrated_run):
    """Type A (the regression's standard error), type B (the stated calibration uncertainties),
    and the coverage of U; the table's heads say which column is which."""
    page, _ = _page(calibrated_run)
    note = re.search(r"Units: .*?</p>", page, re.S).group(0)
    assert "one statistical standard uncertainty of the regression (type A)" in note
    assert "systematic u: the stated calibration standard uncertainties (type B) carried through the fit" in note
    assert "a coverage probability of about 95 %" in note
    assert "std error<br>(statistical, type A)" in page and "systematic u<br>(calibration, type B)" in page


def test_each_table_heading_sits_under_its_section_and_the_units_note_typesets_u(calibrated_run):
    """The consistency table's heading (h4) fell under the coherence table's h3, after an empty
    'Measurement': the two systems compared have a section of their own, the coherence table is
    Measurement's; the units note wrote 'u_* columns' raw beside the tables' u<sub>*</sub>."""
    page, _ = _page(calibrated_run)
    sections = re.findall(r"<h([23])>(.*?)</h\1>|<h4>(.*?)</h4>", page)
    under = {}
    h3 = ""
    for level, title, h4 in sections:
        h3 = title if level == "3" else "" if level == "2" else h3
        if h4:
            under[h4] = h3
    assert under["Two load measuring systems: consistency"] == "Both load measuring systems"
    assert under["Coherence between motion and force signals"] == "Measurement"
    assert under["Derived quantities"] in ("piezo load cells", "strain load cells")
    units = re.search(r"<p class=\"muted\">Units: .*?</p>", page, re.S).group(0)
    assert "Welch-Satterthwaite" in units and "infinite with u<sub>*</sub> columns" in units and "u_*" not in units
