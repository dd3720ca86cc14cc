"""HTML tables of one load measuring system's identifications for ``index.html``.

Per identification: every coefficient with its value, statistical standard uncertainty,
95 % interval, statistical only (of the fit's own kind, named in its column: normal with the
phasor uncertainties u_*, else Student t; the exports' interval_95 is value -+ U), systematic (type B) standard uncertainty and combined expanded
uncertainty (k = 2) where the run stored its budget, "n.d." where that U exceeds the value
(not determined), the simulator's true value (the fit's own truth: the true Z projected onto
its model, where the run stored it; else the constant best fit); the fit's
quality (frequencies, degrees of freedom, condition number, residual, chi2 and p, AIC, BIC,
force errors); its warnings and notes. Then the model-adequacy verdicts and the derived
quantities (whirl frequency ratio, zero crossings of the effective damping) +- k standard
uncertainties on the basis the exports give them (combined where the run stored a budget), at the
planned orbit frequencies the exports' rows name (the measured speeds beside them).
Display units: MN/m, kN s/m, kg (rigunits.display_unit); frequencies in Hz and Omega/omega.
Uncertainties to 2 significant digits; a value, its interval and its truth to the decimal of its
standard error, a derived quantity to that of its +- (orbitrig.analysis.rounding).
"""

from __future__ import annotations

import html
import math
from collections.abc import Sequence

import numpy as np

from orbitrig.analysis.quality import (
    INTERVAL_TEXT,
    LmsComparison,
    Verdict,
    coefficient_rows,
    derived_basis,
    derived_k,
    has_budget,
    interval_kind,
    warnings_of,
)
from orbitrig.analysis.reduce import Reduced, own_truth
from orbitrig.analysis.rounding import (
    at_decimals,
    number,
    orbit_frequency,
    speed_ratio,
    uncertainty_decimals,
    with_uncertainty,
)
from orbitrig.analysis.typeset import entry_html, message_html, sub_html
from reduction.adequacy import Adequacy
from reduction.derived import Derived
from reduction.statistics import CHI2_ALPHA, p_text
from reduction.systematic import LmsAgreement, UncertaintyBasis
from orbitrig.store.stored_run import Frequency
from reduction.whirl import Whirl
from rigunits import HZ, display_unit, in_hz

D_SENTENCE = (
    "D is an apparent inertia (added mass): it absorbs everything that grows with \u03a9\u00b2, "
    "not only the fluid's own inertia (e.g. the recesses' compressibility, an uncorrected delay "
    "of the measuring chain)."
)


def fmt(value, digits: int = 4) -> str:
    """A number for the page, '-' for None / NaN / inf."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "-"
    return f"{value:.{digits}g}"


def _u(u: float | None, scale: float) -> str:
    """An uncertainty ``u`` (SI) in the display unit ``scale`` to 2 significant digits, trailing zeros kept
    (0.60, 1.0); '-' when missing."""
    shown = None if u is None else u * scale
    return at_decimals(shown, uncertainty_decimals(shown))


def _e(text) -> str:
    return html.escape(str(text))


def _max_fit(ident, what: str) -> float | None:
    """Largest |reproduced - measured| over frequencies and both forces (``fx_<what>``, ``fy_<what>``)."""
    values = [abs(row[k]) for row in ident.fit for k in (f"fx_{what}", f"fy_{what}") if row.get(k) is not None]
    return max(values) if values else None


def _quality(ident) -> list[tuple[str, str]]:
    """The fit's quality rows: (name as HTML, value)."""
    chi2 = "-" if ident.chi2 is None else f"{fmt(ident.chi2, 4)} ({_e(p_text(ident.p_value, 3))})"
    return [
        ("frequencies used", str(ident.n_frequencies)),
        ("degrees of freedom 4n \u2212 p", str(ident.dof)),
        ("condition number", fmt(ident.condition_number, 3)),
        ("residual RMS [N]", fmt(ident.residual_rms, 3)),
        (f"\u03c7\u00b2 (known noise {sub_html('u', '*')})", chi2),
        ("Birge ratio \u221a(\u03c7\u00b2/(4n \u2212 p))", _birge(ident)),
        ("AIC / BIC (lower is better)", f"{fmt(ident.aic, 5)} / {fmt(ident.bic, 5)}"),
        ("max force amplitude error [%]", fmt(_max_fit(ident, "amp_err_pct"), 3)),
        ("max force phase error [deg]", fmt(_max_fit(ident, "phase_err_deg"), 3)),
    ]


def _birge(ident) -> str:
    """sqrt(chi2 / dof) and what it says: above 1 the residuals scatter beyond the stated u_*, and
    the statistical std errors (which take u_* as stated) understate the scatter by that factor."""
    if ident.chi2 is None or ident.dof <= 0:
        return "-"
    r = math.sqrt(ident.chi2 / ident.dof)
    if ident.p_value >= CHI2_ALPHA:
        return f"{r:.3g}"
    return (
        f"{r:.3g}: the residuals scatter {r:.3g} times what the stated {sub_html('u', '*')} give; the std "
        f"errors and U take {sub_html('u', '*')} as stated"
    )


def identification_table(r: Reduced, truth: dict[str, float], label: str, with_budget: bool) -> str:
    """One identification under heading `label` (fit_label with the method): coefficients with their
    uncertainties, quality rows, warnings, notes."""
    rows = coefficient_rows(r)
    own = own_truth(r)
    truth = own or truth
    nd = not_determined(r)
    k = next((row.k for row in rows if row.k is not None), 2.0)
    head = [
        '<th class="l">coefficient</th>',
        '<th class="l">unit</th>',
        "<th>value</th>",
        "<th>std error<br>(statistical, type A)</th>",
        f"<th>95 % interval, statistical only<br>({INTERVAL_TEXT[interval_kind(r)][0]})</th>",
    ]
    if with_budget:
        head += ["<th>systematic u<br>(calibration, type B)</th>", f"<th>expanded U<br>(combined, k = {k:g})</th>"]
    if truth:
        head.append("<th>true (simulator, this model)</th>" if own else "<th>true (simulator)</th>")
    body = []
    for row in rows:
        unit, scale = display_unit(row.key)
        # the value, its interval and its truth to the decimal its standard error supports (2 significant digits)
        places = uncertainty_decimals(None if row.std is None else row.std * scale)
        ci = "-" if row.interval is None else "[{}, {}]".format(*(at_decimals(b * scale, places) for b in row.interval))
        value = at_decimals(row.value * scale, places) + (" <b>n.d.</b>" if row.key in nd else "")
        cells = [value, _u(row.std, scale), ci]
        if with_budget:
            cells += [_u(row.systematic, scale), _u(row.expanded, scale)]
        if truth:
            t = truth.get(row.key)
            cells.append(at_decimals(t * scale, places) if t is not None else "-")
        body.append(
            f'<tr><th class="l">{entry_html(row.key)}</th><td class="l">{_e(unit)}</td>'
            + "".join(f"<td>{c}</td>" for c in cells)
            + "</tr>"
        )
    span = len(head) - 1
    body += [
        f'<tr><th class="l">{name}</th><td colspan="{span}" class="l">{value}</td></tr>'
        for name, value in _quality(r.identification)  # the names as HTML
    ]
    out = [f"<h4>{_e(label)}</h4>", f"<table><tr>{''.join(head)}</tr>{''.join(body)}</table>"]
    judged = f"n.d. = not determined: the expanded uncertainty U (k = {derived_k(r):.3g}) exceeds the value."
    notes = [judged] if nd else []
    notes += [D_SENTENCE] if any(row.key.startswith("D") for row in rows) else []
    if notes:
        out.append('<p class="muted">' + " ".join(_e(n) for n in notes) + "</p>")
    warnings = warnings_of(r)
    if warnings:
        out.append('<ul class="warn">' + "".join(f"<li>warning: {message_html(w)}</li>" for w in warnings) + "</ul>")
    if r.identification.notes:
        out.append(
            '<ul class="muted">' + "".join(f"<li>{message_html(n)}</li>" for n in r.identification.notes) + "</ul>"
        )
    return "\n".join(out)


def lms_tables(results: list[Reduced], truth: dict[str, float], labels: list[str]) -> str:
    """Every identification of one load measuring system; budget columns when the run stored any;
    a note when it did not."""
    with_budget = has_budget(results)
    out = [identification_table(r, truth, label, with_budget) for r, label in zip(results, labels)]
    if results and not with_budget:
        out.append(
            '<p class="muted">Systematic (calibration) uncertainty: not stored in this run; '
            "the uncertainties above are statistical only.</p>"
        )
    return "\n".join(out)


def verdict_list(verdicts: list[Verdict], labels: dict[int, str]) -> str:
    """Model adequacy: 'frequency dependence supported: yes/no (p = ...)' per frequency-dependent
    fit, with the test's statistic, degrees of freedom and level (a reader can check the p), the
    AIC/BIC of the constant and the dependent fit, and the dependent fit's own chi2 test."""
    if not verdicts:
        return '<p class="muted">No frequency-dependent model identified: no adequacy test.</p>'
    items = []
    for v in verdicts:
        a = v.adequacy
        extra = (
            ""
            if a is None
            else (
                f" \u2014 {_test_words(a)}, supported when p &lt; {100 * a.alpha:g} %; AIC {fmt(a.aic[0], 5)} "
                f"(constant) vs {fmt(a.aic[1], 5)}; BIC {fmt(a.bic[0], 5)} vs {fmt(a.bic[1], 5)}"
                f"{_own_chi2(v.dependent.identification)}"
            )
        )
        items.append(
            f"<li><b>{_e(labels.get(id(v.dependent), v.dependent.model))}</b>: {message_html(v.text)}{extra}</li>"
        )
    return f'<ul class="verdict">{"".join(items)}</ul>'


def _test_words(a: Adequacy) -> str:
    """The adequacy test's statistic on its degrees of freedom, in words."""
    if a.test == "F":
        return f"F test: F = {fmt(a.statistic, 4)} on ({a.dof[0]}, {a.dof[1]}) degrees of freedom"
    return (
        f"likelihood ratio test: \u03c7\u00b2 of the constant fit \u2212 \u03c7\u00b2 of this one = "
        f"{fmt(a.statistic, 4)} on {a.dof[0]} degrees of freedom (the coefficients added)"
    )


def _own_chi2(ident) -> str:
    """'; this fit alone: chi2 = ... on dof (p = ...)': whether the dependent model itself fits
    within the stated uncertainties; empty without u_* (no chi2)."""
    if ident.chi2 is None:
        return ""
    return (
        f"; this fit alone: \u03c7\u00b2 = {fmt(ident.chi2, 4)} on {ident.dof} degrees of freedom "
        f"({_e(p_text(ident.p_value, 3))})"
    )


def derived_table(
    derived: list[tuple[Reduced, Derived]], labels: dict[int, str], spin: float, blocks: Sequence[Frequency] = ()
) -> str:
    """WFR at the lowest and highest tested Omega (each column named by its planned orbit frequency,
    as the exports' rows; the speeds measured in `blocks`, the point's, beside it) and the zero
    crossings of C_eff, +- k std (k of each fit's U, quality.derived_k, as the derived figure's zero
    crossings; std on the covariance the exports use: combined where the run stored a budget,
    quality.derived_basis)."""
    if not derived:
        return ""
    ks = {id(r): derived_k(r) for r, _ in derived}

    def pm(value, std, k, scale=1.0) -> str:  # the value to the decimal of its k std (2 significant digits)
        if std is None or not np.isfinite(std):
            return fmt(value * scale)
        return with_uncertainty(value * scale, k * std * scale)

    def zero(z, k) -> str:
        if z is None:
            return "none in the tested range"
        hz = 1 / HZ
        return f"{pm(z[0], z[1], k, hz)} Hz (\u03a9/\u03c9 = {speed_ratio(z[0] / spin)})"

    rows = []
    for r, d in derived:
        wfr_std, k = d.wfr_std if d.wfr_std is not None else [None] * len(d.wfr), ks[id(r)]
        rows.append(
            f'<tr><td class="l">{_e(labels.get(id(r), r.model))}</td><td>{pm(d.wfr[0], wfr_std[0], k)}</td>'
            f"<td>{pm(d.wfr[-1], wfr_std[-1], k)}</td><td>{zero(d.c_eff_zero_xx, k)}</td>"
            f"<td>{zero(d.c_eff_zero_yy, k)}</td></tr>"
        )
    head = (
        '<tr><th class="l">identification</th>'
        + "".join(f"<th>WFR at {_planned(w, blocks)}</th>" for w in derived[0][1].orbit[[0, -1]])
        + "".join(
            f"<th>{sub_html('C', 'eff,' + e)} = {entry_html('C' + e)} {sign} {entry_html(cross)}/\u03a9 = 0 at</th>"
            for e, sign, cross in (("xx", "\u2212", "Kxy"), ("yy", "+", "Kyx"))
        )
        + "</tr>"
    )
    return (
        f"<table>{head}{''.join(rows)}</table>"
        f'<p class="muted">\u00b1 {_e(_derived_note(derived, ks))}, linearised for WFR and '
        "the zero crossings; the basis of the exports' derived _std.</p>"
    )


def _planned(orbit: float, blocks: Sequence[Frequency]) -> str:
    """The planned orbit frequency `orbit` (rad/s) as the report states it, with the speeds measured
    on the timing disk in the blocks planned at it: '5 Hz<br>(measured 4.99973 Hz forward,
    4.99999 Hz backward)'; the plain frequency when none was measured."""
    measured = [
        f"{number(in_hz(f.measured_orbit_speed), digits=6)} Hz {Whirl.of(f.direction)}"
        for f in sorted(blocks, key=lambda f: -f.direction)
        if f.complete and math.isclose(abs(f.orbit), orbit, rel_tol=1e-12) and f.measured_orbit_speed > 0
    ]
    return orbit_frequency(in_hz(orbit)) + (
        f'<br><span class="muted">(measured {", ".join(measured)})</span>' if measured else ""
    )


def _derived_note(derived: list[tuple[Reduced, Derived]], ks: dict[int, float]) -> str:
    """'k = 2 standard uncertainties (combined: statistical and calibration)' for the fits shown."""
    words = {
        UncertaintyBasis.COMBINED: "combined: statistical and the stated calibration uncertainty",
        UncertaintyBasis.STATISTICAL: "statistical only",
    }
    parts = dict.fromkeys(f"k = {ks[id(r)]:.3g} standard uncertainties ({words[derived_basis(r)]})" for r, _ in derived)
    return "; ".join(parts)


#: what the E_n of the page were computed with, per basis and whether the run stored them
BASIS_TEXT = {
    (UncertaintyBasis.COMBINED, True): (
        "the combined uncertainties of both fits (statistical and the rig's stated calibration "
        "uncertainty), as the sweep stored them"
    ),
    (UncertaintyBasis.STATISTICAL, True): (
        "the statistical uncertainties of both fits (the rig stated no calibration uncertainty), "
        "as the sweep stored them"
    ),
    (UncertaintyBasis.STATISTICAL, False): (
        "the statistical uncertainties of both fits, repeated here (the run stored no comparison)"
    ),
}


def consistency_table(a: Reduced, b: Reduced, comparison: LmsComparison, label: str) -> str:
    """The two load measuring systems' coefficients of one model side by side with their
    relative difference (a - b) / |a| and the normalised difference E_n = (a - b) / u(a - b), one
    sign for both (1; E_n marked beyond the family-wise
    per-coefficient limit), and the joint chi2 verdict at its level (5 %), all on the
    comparison's uncertainty basis (the sweep's stored one where it exists)."""
    ag = comparison.agreement
    rows, en, mark, nd = [], ag.e_n, ag.e_n_limit(), not_determined(a) | not_determined(b)
    for key, va in a.identification.coefficients.items():
        vb = b.identification.coefficients.get(key)
        unit, scale = display_unit(key)
        rel = "-" if vb is None or va == 0 else "n.d." if key in nd else f"{100 * (va - vb) / abs(va):+.2f}"
        e = en.get(key)
        cell = "-" if e is None else f"{e:+.2f}"
        cls = ' class="err"' if e is not None and mark is not None and abs(e) > mark else ""
        rows.append(
            f'<tr><th class="l">{entry_html(key)}</th><td class="l">{_e(unit)}</td><td>{fmt(va * scale)}</td>'
            f"<td>{fmt(None if vb is None else vb * scale)}</td><td>{rel}</td><td{cls}>{cell}</td></tr>"
        )
    head = (
        f'<tr><th class="l">{_e(label)}</th><th class="l">unit</th><th>{_e(a.lms)}</th><th>{_e(b.lms)}</th>'
        f"<th>({_e(a.lms)} \u2212 {_e(b.lms)}) / |{_e(a.lms)}| [%]</th><th>E<sub>n</sub></th></tr>"
    )
    return (
        f"<h4>Two load measuring systems: consistency</h4><table>{head}{''.join(rows)}</table>"
        f'<p class="muted">E<sub>n</sub> = (a - b) / u(a - b), a = {_e(a.lms)}, b = {_e(b.lms)}, with '
        f"{_e(BASIS_TEXT[(comparison.basis, comparison.stored)])}. "
        f"{_e(_joint_verdict(ag))}"
        + (" n.d.: not determined by one of the two (U exceeds the value): no relative difference." if nd else "")
        + "</p>"
    )


def not_determined(r: Reduced) -> set[str]:
    """The coefficients the sweep stored as not determined for this fit (U exceeds the value)."""
    return set((r.stored or {}).get("not_determined") or [])


def _joint_verdict(ag: LmsAgreement) -> str:
    """The joint test in words, and the per-coefficient limit the marks use."""
    if ag.chi2 is None or ag.limit is None:
        return "Not compared jointly: no uncertainty."
    verdict = "consistent" if ag.consistent else "NOT consistent"
    return (
        f"All coefficients at once: {verdict}, chi2 = {ag.chi2:.3g} on {ag.dof} "
        f"{'<=' if ag.consistent else '>'} {ag.limit:.3g} (false-flag probability {100 * ag.level:g} %); "
        f"one coefficient alone is marked beyond |E_n| = {ag.e_n_limit():.2f} (Sidak, same level)."
    )
