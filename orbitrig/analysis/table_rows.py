"""The report's tables of one load measuring system as rows of text, built once for both places
that show them: the page (``index.html``, orbitrig.analysis.report_tables writes them as HTML)
and ``report.pdf``'s table pages (orbitrig.analysis.report_pages draws them with matplotlib).

A text is plain, with one markup for a subscript: ``K_{xx}`` (the page: K<sub>xx</sub>; a
figure: K$_\\mathrm{xx}$, :func:`as_html`, :func:`as_math`); ``\\n`` breaks a heading's line.
Numbers are rounded as orbitrig.analysis.rounding says (an uncertainty to 2 significant digits,
a value to the decimal of its standard error) and keep the ASCII hyphen: each place writes its
minus signs (rounding.typeset_minus).
"""

from __future__ import annotations

import html
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from orbitrig.analysis.quality import (
    INTERVAL_TEXT,
    CoefficientRow,
    LmsComparison,
    Verdict,
    coefficient_rows,
    derived_basis,
    derived_k,
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
from orbitrig.analysis.typeset import entry_marked, message_marked
from orbitrig.load_systems import DIFFERENCE_WORDS
from orbitrig.store.stored_run import Frequency
from reduction.adequacy import Adequacy
from reduction.derived import Derived
from reduction.statistics import CHI2_ALPHA, p_text
from reduction.lms_comparison import LmsAgreement
from reduction.systematic import UncertaintyBasis
from reduction.whirl import Whirl
from rigunits import HZ, display_unit, in_hz

_SUB = re.compile(r"_\{([^}]*)\}")
#: a value's mark where the sweep judged the coefficient not determined (U exceeds the value)
ND = "n.d."

#: the sign convention every table's coefficients follow (docs/orbit-table.md, README's Conventions;
#: as the ROSS export states it, ross_export): under each system's tables on the page and at the
#: foot of every table page of report.pdf
SIGN_CONVENTION = (
    "Sign convention: f = \u2212(K d + C \u1e0b + D d\u0308) = \u2212Z d, Z(\u03a9) = K + i\u03a9C \u2212 \u03a9\u00b2D, "
    "f the fluid-film force on the journal, positive along +x and +y, d = (x, y) the journal's displacement "
    "in the bearing (K_{xy}: the force in x per displacement in y); \u03a9 > 0 the orbit frequency, one Z for "
    "both whirl directions: the direction lies in the displacement phasors (forward whirl, with the spin "
    f"from +x towards +y, y = \u2212i x; backward y = +i x); the two systems' difference is {DIFFERENCE_WORDS}."
)

D_SENTENCE = (
    "D is an apparent inertia (added mass): it absorbs everything that grows with \u03a9\u00b2, "
    "not only the fluid's own inertia (e.g. the recesses' compressibility, an uncorrected delay "
    "of the measuring chain)."
)


def as_html(text: str) -> str:
    """A text of the markup as the page writes it: escaped, ``K_{xx}`` as K<sub>xx</sub>, line breaks <br>."""
    return _SUB.sub(r"<sub>\1</sub>", html.escape(text)).replace("\n", "<br>")


def as_math(text: str) -> str:
    """A text of the markup as a figure writes it (mathtext): ``K_{xx}`` as ``K$_\\mathrm{xx}$``."""
    return _SUB.sub(r"$_\\mathrm{\1}$", text.replace("$", r"\$"))


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


@dataclass
class Table:
    """One table: its heading, column heads, rows of cells (texts of the markup), the cells marked
    (``marked``: (row, column); an n.d. value, an E_n beyond its limit), the rows of one name and one
    value across the other columns (``spans``: a fit's quality), and below it: ``remarks`` (sentences
    on how to read it), the fit's ``warnings`` and ``notes``."""

    title: str
    head: list[str]
    rows: list[list[str]]
    marked: set[tuple[int, int]] = field(default_factory=set)
    spans: list[tuple[str, str]] = field(default_factory=list)
    remarks: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    names: int = 2  # the leading columns of names and units (set flush left; the numbers after them flush right)


def _max_fit(ident, what: str) -> float | None:
    """Largest |reproduced - measured| over frequencies and both forces (``fx_<what>``, ``fy_<what>``)."""
    values = [abs(row[k]) for row in ident.fit for k in (f"fx_{what}", f"fy_{what}") if row.get(k) is not None]
    return max(values) if values else None


def _quality(ident) -> list[tuple[str, str]]:
    """The fit's quality rows: (name, value)."""
    chi2 = "-" if ident.chi2 is None else f"{fmt(ident.chi2, 4)} ({p_text(ident.p_value, 3)})"
    return [
        ("frequencies used", str(ident.n_frequencies)),
        ("degrees of freedom 4n \u2212 p", str(ident.dof)),
        ("condition number", fmt(ident.condition_number, 3)),
        ("residual RMS [N]", fmt(ident.residual_rms, 3)),
        ("\u03c7\u00b2 (known noise u_{*})", chi2),
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
    return f"{r:.3g}: the residuals scatter {r:.3g} times what the stated u_{{*}} give; the std errors and U take u_{{*}} as stated"


def identification_rows(r: Reduced, truth: dict[str, float], label: str, with_budget: bool) -> Table:
    """One identification under heading `label`: each coefficient's value, standard error, 95 %
    interval, systematic u and expanded U with its k (`with_budget`), truth; quality, warnings, notes."""
    rows, own = coefficient_rows(r), own_truth(r)
    truth, nd = own or truth, not_determined(r)
    head = ["coefficient", "unit", "value", "std error\n(statistical, type A)"]
    head.append(f"95 % interval, statistical only\n({INTERVAL_TEXT[interval_kind(r)][0]})")
    if with_budget:
        head += ["systematic u\n(calibration, type B)", "expanded U\n(combined, 95.45 %)", "k\n(of U)"]
    if truth:
        head.append("true (simulator, this model)" if own else "true (simulator)")
    table = Table(label, head, [])
    for row in rows:
        unit, scale = display_unit(row.key)
        # the value, its interval and its truth to the decimal its standard error supports (2 significant digits)
        places = uncertainty_decimals(None if row.std is None else row.std * scale)
        ci = "-" if row.interval is None else "[{}, {}]".format(*(at_decimals(b * scale, places) for b in row.interval))
        value = at_decimals(row.value * scale, places)
        if row.key in nd:
            table.marked.add((len(table.rows), 2))
            value += f" {ND}"
        cells = [entry_marked(row.key), unit, value, _u(row.std, scale), ci]
        if with_budget:
            cells += [_u(row.systematic, scale), _u(row.expanded, scale), "-" if row.k is None else f"{row.k:.3g}"]
        if truth:
            t = truth.get(row.key)
            cells.append(at_decimals(t * scale, places) if t is not None else "-")
        table.rows.append(cells)
    table.spans = _quality(r.identification)
    if nd:
        table.remarks.append(
            f"n.d. = not determined: the expanded uncertainty U ({_k_words(rows, derived_k(r))}) exceeds the value."
        )
    table.remarks += [D_SENTENCE] if any(row.key.startswith("D") for row in rows) else []
    table.warnings = [message_marked(w) for w in warnings_of(r)]
    table.notes = [message_marked(n) for n in r.identification.notes]
    return table


def _k_words(rows: list[CoefficientRow], k: float) -> str:
    """'k = 2.37' when every row's U has one k (``k`` when no row states its own), else 'k of its row'."""
    ks = {f"{row.k:.3g}" for row in rows if row.k is not None}
    return f"k = {ks.pop() if len(ks) == 1 else f'{k:.3g}'}" if len(ks) <= 1 else "k of its row"


#: the note under a system's tables when the run stored no calibration budget
NO_BUDGET = (
    "Systematic (calibration) uncertainty: not stored in this run; the uncertainties above are statistical only."
)


def verdict_items(verdicts: list[Verdict], labels: dict[int, str]) -> list[tuple[str, str]]:
    """Model adequacy, (fit's label, verdict) per frequency-dependent fit: 'frequency dependence
    supported: yes/no (p = ...)' with the test's statistic, degrees of freedom and level, the AIC/BIC of the
    constant and the dependent fit, and the dependent fit's own chi2 test."""
    items = []
    for v in verdicts:
        a = v.adequacy
        extra = (
            ""
            if a is None
            else (
                f" \u2014 {_test_words(a)}, supported when p < {100 * a.alpha:g} %; AIC {fmt(a.aic[0], 5)} "
                f"(constant) vs {fmt(a.aic[1], 5)}; BIC {fmt(a.bic[0], 5)} vs {fmt(a.bic[1], 5)}"
                f"{_own_chi2(v.dependent.identification)}"
            )
        )
        items.append((labels.get(id(v.dependent), v.dependent.model), message_marked(v.text) + extra))
    return items


#: what the page says when a system has no frequency-dependent fit
NO_VERDICT = "No frequency-dependent model identified: no adequacy test."


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
    return f"; this fit alone: \u03c7\u00b2 = {fmt(ident.chi2, 4)} on {ident.dof} degrees of freedom ({p_text(ident.p_value, 3)})"


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


def consistency_rows(a: Reduced, b: Reduced, comparison: LmsComparison, label: str) -> Table:
    """The two load measuring systems' coefficients of one model side by side with their relative
    difference (a - b) / |a| and the normalised difference E_n = (a - b) / u(a - b) (marked beyond the
    family-wise per-coefficient limit), and the joint chi2 verdict at its level, all on the
    comparison's uncertainty basis (the sweep's stored one where it exists)."""
    ag = comparison.agreement
    en, mark, nd = ag.e_n, ag.e_n_limit(), not_determined(a) | not_determined(b)
    head = [label, "unit", str(a.lms), str(b.lms), f"({a.lms} \u2212 {b.lms}) / |{a.lms}| [%]", "E_{n}"]
    table = Table("Two load measuring systems: consistency", head, [])
    std_a, std_b = ({row.key: row.std for row in coefficient_rows(r)} for r in (a, b))
    for key, va in a.identification.coefficients.items():
        vb = b.identification.coefficients.get(key)
        unit, scale = display_unit(key)
        rel = "-" if vb is None or va == 0 else ND if key in nd else f"{100 * (va - vb) / abs(va):+.2f}"
        e = en.get(key)
        if e is not None and mark is not None and abs(e) > mark:
            table.marked.add((len(table.rows), 5))
        pair = [_as_its_table(va, std_a.get(key), scale), _as_its_table(vb, std_b.get(key), scale)]
        cells = [entry_marked(key), unit, *pair, rel]
        table.rows.append(cells + ["-" if e is None else f"{e:+.2f}"])
    table.remarks.append(
        f"E_{{n}} = (a \u2212 b) / u(a \u2212 b), a = {a.lms}, b = {b.lms}, with {BASIS_TEXT[(comparison.basis, comparison.stored)]}. "
        + _joint_verdict(ag)
        + (" n.d.: not determined by one of the two (U exceeds the value): no relative difference." if nd else "")
    )
    return table


def _as_its_table(value: float | None, std: float | None, scale: float) -> str:
    """A coefficient (SI) at its display `scale` as its identification's table writes it: to the
    decimal of its standard error `std` (2 significant digits), 4 significant digits without one."""
    if value is None:
        return "-"
    return at_decimals(value * scale, uncertainty_decimals(None if std is None else std * scale))


def not_determined(r: Reduced) -> set[str]:
    """The coefficients the sweep stored as not determined for this fit (U exceeds the value)."""
    return set((r.stored or {}).get("not_determined") or [])


#: the joint test's "at most" sign
LE = "\u2264"


def _joint_verdict(ag: LmsAgreement) -> str:
    """The joint test in words, and the per-coefficient limit the marks use."""
    if ag.chi2 is None or ag.limit is None:
        return "Not compared jointly: no uncertainty."
    verdict = "consistent" if ag.consistent else "NOT consistent"
    return (
        f"All coefficients at once: {verdict}, \u03c7\u00b2 = {ag.chi2:.3g} on {ag.dof} "
        f"{LE if ag.consistent else '>'} {ag.limit:.3g} (false-flag probability {100 * ag.level:g} %); "
        f"one coefficient alone is marked beyond |E_{{n}}| = {ag.e_n_limit():.2f} (\u0160id\u00e1k, same level)."
    )


def derived_rows(
    derived: list[tuple[Reduced, Derived]], labels: dict[int, str], spin: float, blocks: Sequence[Frequency] = ()
) -> Table | None:
    """WFR at the lowest and highest tested Omega (each column named by its planned orbit frequency,
    as the exports' rows; the speeds measured in `blocks`, the point's, below it) and the zero
    crossings of C_eff, +- k std (k of each fit's U, quality.derived_k, as the derived figure's zero
    crossings; std on the covariance the exports use: combined where the run stored a budget,
    quality.derived_basis); None without derived quantities."""
    if not derived:
        return None
    ks = {id(r): derived_k(r) for r, _ in derived}

    def pm(value, std, k, scale=1.0) -> str:  # the value to the decimal of its k std (2 significant digits)
        if std is None or not np.isfinite(std):
            return fmt(value * scale)
        return with_uncertainty(value * scale, k * std * scale)

    def zero(z, k) -> str:
        if z is None:
            return "none in the tested range"
        return f"{pm(z[0], z[1], k, 1 / HZ)} Hz (\u03a9/\u03c9 = {speed_ratio(z[0] / spin)})"

    head = ["identification"] + [f"WFR at {_planned(w, blocks)}" for w in derived[0][1].orbit[[0, -1]]]
    head += [
        f"C_{{eff,{e}}} = {entry_marked('C' + e)} {sign} {entry_marked(cross)}/\u03a9 = 0 at"
        for e, sign, cross in (("xx", "\u2212", "Kxy"), ("yy", "+", "Kyx"))
    ]
    table = Table("Derived quantities", head, [], names=1)  # the fit's name, then numbers only
    for r, d in derived:
        wfr_std, k = d.wfr_std if d.wfr_std is not None else [None] * len(d.wfr), ks[id(r)]
        table.rows.append(
            [
                labels.get(id(r), r.model),
                pm(d.wfr[0], wfr_std[0], k),
                pm(d.wfr[-1], wfr_std[-1], k),
                zero(d.c_eff_zero_xx, k),
                zero(d.c_eff_zero_yy, k),
            ]
        )
    table.remarks.append(
        f"\u00b1 {_derived_note(derived, ks)}, linearised for WFR and the zero crossings; "
        "the exports give the derived quantities' standard uncertainties (their columns ending in _std) on this basis."
    )
    return table


def _planned(orbit: float, blocks: Sequence[Frequency]) -> str:
    """The planned orbit frequency `orbit` (rad/s) as the report states it, with the speeds measured
    on the timing disk in the blocks planned at it on a line below: '5 Hz\\n(measured 4.99973 Hz
    forward, 4.99999 Hz backward)'; the plain frequency when none was measured."""
    measured = [
        f"{number(in_hz(f.measured_orbit_speed), digits=6)} Hz {Whirl.of(f.direction)}"
        for f in sorted(blocks, key=lambda f: -f.direction)
        if f.complete and math.isclose(abs(f.orbit), orbit, rel_tol=1e-12) and f.measured_orbit_speed > 0
    ]
    return orbit_frequency(in_hz(orbit)) + (f"\n(measured {', '.join(measured)})" if measured else "")


def _derived_note(derived: list[tuple[Reduced, Derived]], ks: dict[int, float]) -> str:
    """'k = 2 standard uncertainties (combined: statistical and calibration)' for the fits shown."""
    words = {
        UncertaintyBasis.COMBINED: "combined: statistical and the stated calibration uncertainty",
        UncertaintyBasis.STATISTICAL: "statistical only",
    }
    parts = dict.fromkeys(f"k = {ks[id(r)]:.3g} standard uncertainties ({words[derived_basis(r)]})" for r, _ in derived)
    return "; ".join(parts)
