"""HTML tables of one load measuring system's identifications for ``index.html``, written from the
rows orbitrig.analysis.table_rows builds (report.pdf's table pages draw the same rows).

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
from collections.abc import Sequence

from orbitrig.analysis.quality import LmsComparison, Verdict, has_budget
from orbitrig.analysis.reduce import Reduced
from orbitrig.analysis.table_rows import (
    ND,
    derived_rows,
    NO_BUDGET,
    NO_VERDICT,
    SIGN_CONVENTION,
    as_html,
    consistency_rows,
    identification_rows,
    verdict_items,
)
from reduction.derived import Derived
from orbitrig.store.stored_run import Frequency


_ERR = ' class="err"'


def _e(text) -> str:
    return html.escape(str(text))


def identification_table(r: Reduced, truth: dict[str, float], label: str, with_budget: bool) -> str:
    """One identification under heading `label` (fit_label with the method): coefficients with their
    uncertainties, quality rows, warnings, notes (the rows of table_rows.identification_rows)."""
    t = identification_rows(r, truth, label, with_budget)
    head = "".join(
        f'<th class="l">{as_html(h)}</th>' if c < 2 else f"<th>{as_html(h)}</th>" for c, h in enumerate(t.head)
    )
    body = []
    for i, (name, unit, *cells) in enumerate(t.rows):
        if (i, 2) in t.marked:  # the value's n.d. in bold
            cells[0] = f"{as_html(cells[0].removesuffix(' ' + ND))} <b>{ND}</b>"
        else:
            cells[0] = as_html(cells[0])
        cells[1:] = [as_html(c) for c in cells[1:]]
        body.append(
            f'<tr><th class="l">{as_html(name)}</th><td class="l">{as_html(unit)}</td>'
            + "".join(f"<td>{c}</td>" for c in cells)
            + "</tr>"
        )
    span = len(t.head) - 1
    body += [
        f'<tr><th class="l">{as_html(name)}</th><td colspan="{span}" class="l">{as_html(value)}</td></tr>'
        for name, value in t.spans
    ]
    out = [f"<h4>{as_html(label)}</h4>", f"<table><tr>{head}</tr>{''.join(body)}</table>"]
    if t.remarks:
        out.append('<p class="muted">' + " ".join(as_html(n) for n in t.remarks) + "</p>")
    if t.warnings:
        out.append('<ul class="warn">' + "".join(f"<li>warning: {as_html(w)}</li>" for w in t.warnings) + "</ul>")
    if t.notes:
        out.append('<ul class="muted">' + "".join(f"<li>{as_html(n)}</li>" for n in t.notes) + "</ul>")
    return "\n".join(out)


def lms_tables(results: list[Reduced], truth: dict[str, float], labels: list[str]) -> str:
    """Every identification of one load measuring system; budget columns when the run stored any;
    a note when it did not; the sign convention their coefficients follow."""
    with_budget = has_budget(results)
    out = [identification_table(r, truth, label, with_budget) for r, label in zip(results, labels)]
    if results and not with_budget:
        out.append(f'<p class="muted">{as_html(NO_BUDGET)}</p>')
    if results:
        out.append(f'<p class="muted">{as_html(SIGN_CONVENTION)}</p>')
    return "\n".join(out)


def verdict_list(verdicts: list[Verdict], labels: dict[int, str]) -> str:
    """Model adequacy (table_rows.verdict_items) as a list."""
    if not verdicts:
        return f'<p class="muted">{as_html(NO_VERDICT)}</p>'
    items = "".join(
        f"<li><b>{as_html(label)}</b>: {as_html(text)}</li>" for label, text in verdict_items(verdicts, labels)
    )
    return f'<ul class="verdict">{items}</ul>'


def derived_table(
    derived: list[tuple[Reduced, Derived]], labels: dict[int, str], spin: float, blocks: Sequence[Frequency] = ()
) -> str:
    """The derived quantities (the rows of table_rows.derived_rows): each column's measured speeds
    below its planned orbit frequency, muted."""
    t = derived_rows(derived, labels, spin, blocks)
    if t is None:
        return ""

    def heading(h: str) -> str:
        first, _, more = h.partition("\n")
        return as_html(first) + (f'<br><span class="muted">{as_html(more)}</span>' if more else "")

    head = '<tr><th class="l">identification</th>' + "".join(f"<th>{heading(h)}</th>" for h in t.head[1:]) + "</tr>"
    rows = "".join(
        f'<tr><td class="l">{as_html(row[0])}</td>' + "".join(f"<td>{as_html(c)}</td>" for c in row[1:]) + "</tr>"
        for row in t.rows
    )
    return f'<table>{head}{rows}</table><p class="muted">{" ".join(as_html(n) for n in t.remarks)}</p>'


def consistency_table(a: Reduced, b: Reduced, comparison: LmsComparison, label: str) -> str:
    """The two load measuring systems' coefficients of one model side by side (the rows of
    table_rows.consistency_rows), an E_n beyond its limit marked."""
    t = consistency_rows(a, b, comparison, label)
    head = "".join(
        f'<th class="l">{as_html(h)}</th>' if c < 2 else f"<th>{as_html(h)}</th>" for c, h in enumerate(t.head)
    )
    rows = "".join(
        f'<tr><th class="l">{as_html(row[0])}</th><td class="l">{as_html(row[1])}</td>'
        + "".join(f"<td{_ERR if (i, c) in t.marked else ''}>{as_html(v)}</td>" for c, v in enumerate(row[2:], start=2))
        + "</tr>"
        for i, row in enumerate(t.rows)
    )
    notes = " ".join(as_html(n) for n in t.remarks)
    return f'<h4>{as_html(t.title)}</h4><table><tr>{head}</tr>{rows}</table><p class="muted">{notes}</p>'
