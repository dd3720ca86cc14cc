"""``DIR/plots/index.html``: one self-contained page (inline CSS, no scripts, no
network) showing the run's status and settings, and per operating point the
plots, the coefficient tables (value and standard error, with units; true
values in ``--sim`` runs) and the coherence table (the paper's Table 1).
Images are referenced by relative name, so the ``plots`` folder can be moved
or archived as a whole."""

from __future__ import annotations

import html
import math
import os
import re
from pathlib import Path

import numpy as np


from orbitrig.analysis.plots_coherence import BANDS, band_colour, coherence_table
from orbitrig.analysis.reduce import true_constants
from orbitrig.analysis.quality import COMBINED_K, dof_notes, has_budget, interval_sentence
from orbitrig.analysis.report_analysis import consistency, fit_label
from orbitrig.analysis.report_pdf import provenance_rows, scenario_name
from orbitrig.analysis.report_tables import consistency_table, derived_table, lms_tables, verdict_list
from orbitrig.analysis.table_rows import SIGN_CONVENTION, as_html, fmt
from orbitrig.analysis.rounding import typeset_minus
from orbitrig.analysis.typeset import CONDITIONS, PAIRS, message_html, operating_point_html, pair_html
from orbitrig.load_systems import LMS, LoadSystem
from orbitrig.store.durable import write_atomic
from rigunits import MPA, micrometres, utc_iso

CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;margin:1.5em auto;max-width:1400px;
     color:#222;padding:0 1em}
h1{margin-bottom:.2em} h2{border-bottom:2px solid #ccc;padding-bottom:.2em;margin-top:2em}
table{border-collapse:collapse;margin:.6em 0 1.2em 0;font-size:.9em}
th,td{border:1px solid #ccc;padding:.25em .6em;text-align:right} th{background:#f2f2f2}
td.l,th.l{text-align:left}
.status{display:inline-block;padding:.15em .6em;border-radius:.3em;color:#fff;font-weight:bold}
.completed{background:#2a7d2a}.stopped{background:#b07a00}.aborted,.failed{background:#b02020}
.running,.unknown{background:#555}
.err{color:#b02020;white-space:pre-wrap} .muted{color:#666}
.side{display:flex;gap:1em;align-items:flex-start} .side figure{flex:0 1 65%;margin:0}
.side>div{flex:1 1 35%} .warn{color:#a05000} .verdict li{margin:.3em 0}
.band{padding:0 .5em;margin-right:.3em}
img{max-width:100%;border:1px solid #ddd;margin:.4em 0}
details pre{background:#f7f7f7;padding:.6em;overflow-x:auto}
"""
#: the id of the stored simulator scenario's text on the page (the header's scenario row links it)
SCENARIO_ID = "scenario"


def _e(text) -> str:
    return html.escape(str(text))


def _symbol(column: str) -> str:
    """The symbol of an operating condition (typeset.CONDITIONS) as the page writes it: \u03b5<sub>s</sub>."""
    return CONDITIONS[column].html()


def _named(column: str) -> str:
    """An operating condition in words and by its symbol: static eccentricity \u03b5<sub>s</sub>."""
    return f"{html.escape(CONDITIONS[column].words)} {_symbol(column)}"


def _settings_table(s) -> str:
    rows = [
        ("spin speed " + _symbol("spin"), f"{s.spin_rpm:.0f} rpm ({s.spin:.2f} rad/s)"),
        (_named("recess_pressure"), f"{s.recess_pressure / MPA:.4g} MPa"),
        (_named("pressure_ratio"), fmt(s.pressure_ratio)),
        (_named("static_eccentricity"), fmt(s.static_eccentricity)),
        (_named("dynamic_eccentricity"), fmt(s.dynamic_eccentricity)),
        ("orbit radius (commanded)", micrometres(s.orbit_radius, ".3g")),
    ]
    return "<table>" + "".join(f'<tr><th class="l">{k}</th><td>{v}</td></tr>' for k, v in rows) + "</table>"


def _coherence_table(point) -> str:
    """The paper's Table 1: gamma^2 of the four pairs of each LMS per Omega/omega, each
    cell on the colour of its band (plots_coherence.BANDS, as in coherence_PPPP.png)."""
    table = coherence_table(point.tables)
    if table is None:
        return ""
    head1 = (
        '<tr><th class="l" rowspan="2">\u03a9/\u03c9, whirl</th>'
        + "".join(f'<th colspan="4">{_e(lms)} load cells</th>' for lms in table.lms)
        + "</tr>"
    )
    head2 = "<tr>" + "".join(f"<th>\u03b3\u00b2 {pair_html(v)}</th>" for v in PAIRS) * len(table.lms) + "</tr>"
    rows = "".join(
        f'<tr><td class="l">{_e(label)}</td>'
        + "".join(f'<td style="background:{band_colour(v)}">{fmt_coherence(v)}</td>' for v in values)
        + "</tr>"
        for label, values in zip(table.rows, table.values)
    )
    legend = " ".join(f'<span class="band" style="background:{c}">{_e(t)}</span>' for _, c, t in BANDS)
    return (
        f"<h4>Coherence between motion and force signals</h4><table>{head1}{head2}{rows}</table>"
        f'<p class="muted">\u03b3\u00b2 bands: {legend}. {_e(_records_text(point.tables))}</p>'
    )


def _records_text(tables) -> str:
    """How many revolutions (records) each row's \u03b3\u00b2 is estimated from: a reader needs it to
    judge the estimate (with one record \u03b3\u00b2 is 1 whatever the noise)."""
    counts = [n for t in tables.values() if t.n_records is not None for n in np.asarray(t.n_records, dtype=int)]
    if not counts:
        return "Each \u03b3\u00b2 from the revolutions of its block (their number not stored)."
    lo, hi = min(counts), max(counts)
    n = f"{lo}" if lo == hi else f"{lo} to {hi}"
    return f"Each \u03b3\u00b2 from the {n} revolutions (records) averaged at its orbit frequency."


def fmt_coherence(v: float) -> str:
    return f"{v:.3f}" if math.isfinite(v) else "-"


def _pick(pr, out_dir: Path, taken: set, *names: str) -> list[str]:
    """The figures of `pr` named `names` (stems), in that order, as HTML; marks them taken."""
    by_stem = {Path(p).stem: p for p in pr.plots}
    out = []
    for name in names:
        if name in by_stem and name not in taken:
            taken.add(name)
            out.append(_figure(by_stem[name], out_dir))
    return out


def _lms_section(pr, out_dir: Path, lms: LoadSystem, truth: dict, taken: set) -> list[str]:
    """One load measuring system: refusals, Figure 5 beside the adequacy verdicts, the
    identification tables, coefficient figures, derived quantities, impedance vs truth."""
    p, results = pr.point, pr.results.get(lms, [])
    refused = [i for i in p.identifications if i.lms == lms and not i.ok]
    if not results and not refused:
        return []
    labels = {id(r): fit_label(r) for r in results}
    h = [f"<h3>{_e(lms)} load cells</h3>"]
    h += [f'<p class="err">{_e(i.model)} {_e(i.freq_dep)} refused: {message_html(str(i.error))}</p>' for i in refused]
    forces = _pick(pr, out_dir, taken, f"forces_{p.name}_{lms}")
    if forces:
        h.append(
            '<div class="side">'
            + forces[0]
            + "<div><h4>Model adequacy</h4>"
            + verdict_list(pr.verdicts.get(lms, []), labels)
            + "</div></div>"
        )
    h.append(lms_tables(results, truth, [fit_label(r, name_ols=True) for r in results]))
    h += _pick(
        pr, out_dir, taken, *(f"coefficients_{p.name}_{lms}_{m}" for m in dict.fromkeys(r.model for r in results))
    )
    if pr.derived.get(lms):
        h.append("<h4>Derived quantities</h4>")
        h.append(derived_table(pr.derived[lms], labels, p.settings.spin, p.frequencies))
    h += _pick(pr, out_dir, taken, f"derived_{p.name}_{lms}", f"impedance_{p.name}_{lms}")
    return h


def _point_section(run, pr, out_dir: Path) -> str:
    p = pr.point
    s = p.settings
    h = [f'<h2 id="p{p.name}">Point {p.name}: {operating_point_html(s)}</h2>', _settings_table(s)]
    truth = true_constants(p)
    taken: set = set()
    if pr.mismatches:
        h.append(
            '<p class="err">Repeating the stored identifications gave different numbers:<br>'
            + "<br>".join(_e(m) for m in pr.mismatches)
            + "</p>"
        )
    if pr.unreadable:
        h.append('<p class="err">' + "<br>".join(_e(m) for m in pr.unreadable) + "</p>")
    for lms in LMS:
        h += _lms_section(pr, out_dir, lms, truth, taken)
    both = _pick(pr, out_dir, taken, f"lms_{p.name}")  # the two systems compared: their own section
    if (compared := consistency(pr)) is not None:
        a, b, comparison = compared
        both.insert(0, consistency_table(a, b, comparison, fit_label(a)))
    h += ["<h3>Both load measuring systems</h3>", *both] if both else []
    h.append("<h3>Measurement</h3>")
    h.append(_coherence_table(p))
    h += _pick(pr, out_dir, taken, f"coherence_{p.name}", f"orbits_{p.name}")
    h += [_figure(png, out_dir) for png in pr.plots if Path(png).stem not in taken]  # signals, and any other
    return "\n".join(h)


#: what each figure kind shows (its file name's first word), as the page's caption says it (HTML)
FIGURE_CAPTIONS = {
    "forces": "Measured and reproduced force amplitudes against \u03a9/\u03c9 (paper Fig. 5), filled "
    "markers forward whirl, open backward; below, each fit's residual |measured \u2212 reproduced| "
    "force phasor beside the measured phasor's U",
    "coefficients": "Identified K, C (and D) entries against \u03a9/\u03c9 (paper Figs. 6 and 7), each "
    "y axis with its unit; solid over the tested orbit range, dotted beyond; in simulator runs the "
    "truth as crosses",
    "derived": "Effective damping C<sub>eff,xx</sub> = C<sub>xx</sub> \u2212 K<sub>xy</sub>/\u03a9 and "
    "C<sub>eff,yy</sub> = C<sub>yy</sub> + K<sub>yx</sub>/\u03a9 with their zero crossings, the whirl "
    "frequency ratio, and the forward and backward direct dynamic stiffness H against \u03a9/\u03c9",
    "impedance": "Identified impedance Z(\u03a9), real and imaginary parts, against \u03a9/\u03c9, "
    "beside the simulator's true Z",
    "coherence": "Coherence \u03b3\u00b2 between each displacement and force signal at each orbit "
    "frequency and whirl direction (paper Table 1)",
    "lms": "The two load measuring systems: strain-gauge against piezoelectric forces, and one model's "
    "constant K and C from each",
    "signals": "Time-averaged forces of both load measuring systems with their amplitude and phase "
    "difference, and one raw revolution against the average (paper Fig. 4)",
    "orbits": "Measured x\u2013y orbits of both probe planes (A solid, B dash-dotted), one panel per orbit frequency",
    "summary": "One model's K and C at every operating point",
}
#: the figure kinds with bands or error bars, and what those are
BARS_CAPTION = (
    "Bands and error bars: \u00b1 the expanded uncertainty U = k u, its k and basis (combined "
    "statistical and calibration, or statistical only) as the figure's legend states"
)
BARRED = frozenset({"forces", "coefficients", "derived", "impedance", "lms", "summary"})


#: each figure kind in words, as its title names it (its image's text alternative begins with it)
FIGURE_NAMES = {"forces": "Measured and reproduced forces", "coefficients": "Rotordynamic coefficients"}
FIGURE_NAMES |= {"derived": "Derived quantities", "impedance": "Identified impedance against the true one"}
FIGURE_NAMES |= {"coherence": "Coherence between motion and force signals", "lms": "The two load measuring systems"}
FIGURE_NAMES |= {"signals": "Force signals", "orbits": "Measured orbits", "summary": "Coefficients at every point"}
_WHIRL_WORDS = {"fwd": "forward whirl", "bwd": "backward whirl"}


def figure_alt(stem: str) -> str:
    """A figure's text alternative from its file's name, for a reader who does not see it:
    ``coefficients_0001_piezo_kc8`` -> 'Rotordynamic coefficients, point 0001, piezo load cells, model kc8'."""
    kind, *parts = stem.split("_")
    point = [f"point {parts.pop(0)}"] if parts and len(parts[0]) == 4 and parts[0].isdigit() else []
    systems = {str(lms) for lms in LMS}
    words = [
        f"{p} load cells"
        if p in systems
        else _WHIRL_WORDS.get(p) or (f"orbit frequency no. {int(p) + 1}" if p.isdigit() else f"model {p}")
        for p in parts
    ]
    return ", ".join([FIGURE_NAMES.get(kind, kind), *point, *words])


def _figure(png: Path, out_dir: Path) -> str:
    """The figure with its caption: what it shows and what its bars are (by its kind), and its file."""
    rel = Path(png).relative_to(out_dir)
    name = _e(rel.as_posix())
    kind = rel.stem.split("_")[0]
    says = FIGURE_CAPTIONS.get(kind)
    caption = "" if says is None else f"{says}." + (f" {BARS_CAPTION}." if kind in BARRED else "") + "<br>"
    return (
        f'<figure><a href="{name}"><img src="{name}" alt="{_e(figure_alt(rel.stem))}"></a>'
        f'<figcaption>{caption}<span class="muted">{_e(rel.name)} (full size: click)</span></figcaption></figure>'
    )


def _link(path: Path, out_dir: Path) -> str:
    """The address of the run's file `path` from the page in `out_dir`: relative ('../coefficients.csv'
    in DIR/plots), a file: URI where none is (another drive)."""
    try:
        return Path(os.path.relpath(path.resolve(), out_dir.resolve())).as_posix()
    except ValueError:
        return path.resolve().as_uri()


def _points_table(report) -> str:
    """One row per reported point: its settings, linked to its section."""
    head = (
        '<tr><th>point</th><th class="l">label</th>'
        + "".join(
            f"<th>{_symbol(c)} [{CONDITIONS[c].unit}]</th>" if CONDITIONS[c].unit else f"<th>{_symbol(c)}</th>"
            for c in ("spin", "recess_pressure", "pressure_ratio", "static_eccentricity", "dynamic_eccentricity")
        )
        + "<th>models identified</th></tr>"
    )
    rows = []
    for pr in report.points:
        s = pr.point.settings
        n = sum(len(v) for v in pr.results.values())
        rows.append(
            f'<tr><td><a href="#p{pr.point.name}">{pr.point.name}</a></td><td class="l">{_e(s.label)}</td>'
            f"<td>{s.spin_rpm:.0f}</td><td>{s.recess_pressure / MPA:.4g}</td><td>{fmt(s.pressure_ratio)}</td>"
            f"<td>{fmt(s.static_eccentricity)}</td><td>{fmt(s.dynamic_eccentricity)}</td>"
            f"<td>{n} of {len(pr.point.identifications)}</td></tr>"
        )
    return f"<h2>Operating points</h2><table>{head}{''.join(rows)}</table>"


def _run_table(run, points: str) -> str:
    """The run's header (report_pdf.provenance_rows: report.pdf's first page gives the same), the
    scenario's SHA-256 linked to its stored text, then the points and when the page was written."""
    rows = [(name, _scenario(run) if name == "simulator scenario" else _e(text)) for name, text in provenance_rows(run)]
    rows += [("operating points", _e(points)), ("report written", _e(utc_iso()))]
    cells = "".join(f'<tr><th class="l">{name}</th><td class="l">{cell}</td></tr>' for name, cell in rows if cell)
    return f"<table>{cells}</table>"


def _scenario(run) -> str:
    """The simulator scenario (HTML): report_pdf.scenario_name, and the SHA-256 of its text with a
    link to that text as the run stored it (further down the page); '' for a rig's run."""
    if not run.sim:
        return ""
    label = _e(scenario_name(run))
    if not run.sim_scenario_config:
        return label
    return f'{label}, SHA-256 {run.sim_scenario_sha256} of its <a href="#{SCENARIO_ID}">stored text</a>'


def render(report) -> str:
    run = report.run
    incomplete = [p.name for p in run.points if not p.complete]
    more = f", {len(incomplete)} incomplete ({', '.join(incomplete)})" if incomplete else ""
    head = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>orbitrig run {_e(run.directory.name)}</title><style>{CSS}</style></head><body>",
        f"<h1>orbitrig run <code>{_e(run.directory.name)}</code></h1>",
        f'<p>Status: <span class="status {run.status}">{_e(run.status)}</span> {_e(run.status_message)}</p>',
        _run_table(run, f"{len(run.complete_points)} complete{more}"),
    ]
    if report.points:
        head.append(_points_table(report))
    else:
        head.append('<p class="err">No complete operating point to report.</p>')
    results = [r for pr in report.points for rs in pr.results.values() for r in rs]
    combined = (
        "; systematic u: the stated calibration standard uncertainties (type B) carried through "
        "the fit; expanded U: k times the combined (statistical and systematic) standard uncertainty, "
        f"a coverage probability of about 95 % ({message_html('; '.join([COMBINED_K, *dof_notes(results)]))})"
        if has_budget(results)
        else ""
    )
    head.append(
        '<p class="muted">Units: K in MN/m, C in kN s/m, D in kg (SI at the source). '
        "Std error: one statistical standard uncertainty of the regression (type A); "
        f"{_e(interval_sentence(results))}{combined}. "
        f"Higher-order terms multiply \u03a9^r with \u03a9 in rad/s. {as_html(SIGN_CONVENTION)} The tables' and "
        "figures' \u03a9/\u03c9 is the orbit frequency of either direction over the spin speed.</p>"
    )
    files = sorted(run.directory.glob("*.csv"))
    if files:
        head.append(
            "<p>Tables: "
            + " \u00b7 ".join(f'<a href="{_e(_link(f, report.directory))}">{_e(f.name)}</a>' for f in files)
            + "</p>"
        )
    for name, text, anchor in (
        ("rig configuration", run.rig_config, ""),
        ("matrix configuration", run.matrix_config, ""),
        ("simulator scenario", run.sim_scenario_config, f' id="{SCENARIO_ID}"'),
        ("calibration record", run.calibration_record_text, ""),
    ):
        if text:
            head.append(f"<details{anchor}><summary>{name}</summary><pre>{_e(text)}</pre></details>")
    if report.pdf:
        link = f'<a href="{_e(report.pdf.name)}">{_e(report.pdf.name)}</a>'
        head.append(
            f"<p>The tables and every figure in one file: {link} (each figure's own vector files lie beside its PNG)</p>"
            if report.plots
            else f"<p>The tables in one file: {link} (no figure drawn)</p>"
        )
    if report.summary:
        head.append(_figure(report.summary, report.directory))
    body = [_point_section(run, pr, report.directory) for pr in report.points]
    return minus_signs("\n".join(head + body + ["</body></html>"]))


def write_html(report, path: Path) -> Path:
    path = Path(path)
    write_atomic(path, render(report).encode("utf-8"))
    return path


#: what keeps its hyphens on the page: tags (links, classes), the stored texts as stored (<pre>),
#: the style sheet and code (a run's name)
_VERBATIM = re.compile(r"(<pre.*?</pre>|<style.*?</style>|<code.*?</code>|<[^>]*>)", re.S)


def minus_signs(page: str) -> str:
    """The page with each ASCII hyphen standing for a minus sign in its text written as U+2212
    (rounding.typeset_minus: '−3.499', '[−3.581, −3.417]'); tags, <pre>, <style> and
    <code> as they are. The CSV and JSON files keep ASCII."""
    parts = _VERBATIM.split(page)
    parts[::2] = [typeset_minus(p) for p in parts[::2]]
    return "".join(parts)
