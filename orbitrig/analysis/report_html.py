"""``DIR/plots/index.html``: one self-contained page (inline CSS, no scripts, no
network) showing the run's status and settings, and per operating point the
plots, the coefficient tables (value and standard error, with units; true
values in ``--sim`` runs) and the coherence table (the paper's Table 1).
Images are referenced by relative name, so the ``plots`` folder can be moved
or archived as a whole."""

from __future__ import annotations

import html
import math
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from orbitrig.analysis.plots import PAIR_LABELS, whirl_direction
from orbitrig.analysis.reduce import coefficient_unit, true_constants
from orbitrig.config import LMS

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
img{max-width:100%;border:1px solid #ddd;margin:.4em 0}
details pre{background:#f7f7f7;padding:.6em;overflow-x:auto}
"""

def fmt(value, digits: int = 4) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "-"
    return f"{value:.{digits}g}"


def _e(text) -> str:
    return html.escape(str(text))


def _settings_table(s) -> str:
    rows = [
        ("spin speed \u03c9", f"{s.spin_rpm:.0f} rpm ({s.spin:.2f} rad/s)"),
        ("recess pressure p<sub>r</sub>", f"{s.recess_pressure / 1e6:.4g} MPa"),
        ("pressure ratio \u03b2", fmt(s.pressure_ratio)),
        ("static eccentricity \u03b5<sub>s</sub>", fmt(s.static_eccentricity)),
        ("dynamic eccentricity \u03b5<sub>d</sub>", fmt(s.dynamic_eccentricity)),
        ("orbit radius (commanded)", f"{s.orbit_radius * 1e6:.3g} \u00b5m"),
    ]
    return "<table>" + "".join(f'<tr><th class="l">{k}</th><td>{v}</td></tr>' for k, v in rows) + "</table>"


def _max_fit(ident, what: str) -> float | None:
    """Largest |reproduced - measured| over frequencies and both forces (the fit's
    ``fx_<what>`` / ``fy_<what>`` entries)."""
    values = [abs(row[k]) for row in ident.fit for k in (f"fx_{what}", f"fy_{what}") if row.get(k) is not None]
    return max(values) if values else None


def _coefficient_table(results, truth: dict[str, float]) -> str:
    """Rows = coefficient keys, columns = identifications: value \u00b1 std in display units."""
    keys: list[str] = []
    for r in results:
        keys += [k for k in r.identification.coefficients if k not in keys]
    keys.sort(key=lambda k: ("KCD".index(k[0]), int(k.partition("_")[2] or 0), k))
    head = '<tr><th class="l">coefficient</th><th class="l">unit</th>'
    head += "".join(f"<th>{_e(r.model)} {_e(r.freq_dep)} {_e(r.method)}<br>value \u00b1 std error</th>" for r in results)
    if truth:
        head += "<th>true (simulator)</th>"
    head += "</tr>"
    body = []
    for k in keys:
        unit, scale = coefficient_unit(k)
        cells = []
        for r in results:
            v = r.identification.coefficients.get(k)
            s = r.identification.std_errors.get(k)
            cells.append("<td>-</td>" if v is None else f"<td>{fmt(v * scale)} \u00b1 {fmt(s * scale if s is not None else None, 2)}</td>")
        if truth:
            t = truth.get(k)
            cells.append(f"<td>{fmt(t * scale) if t is not None else '-'}</td>")
        body.append(f'<tr><th class="l">{_e(k)}</th><td class="l">{_e(unit)}</td>{"".join(cells)}</tr>')
    quality = []
    for label, get in (
        ("frequencies used", lambda i: str(i.n_frequencies)),
        ("condition number", lambda i: fmt(i.condition_number, 3)),
        ("residual RMS [N]", lambda i: fmt(i.residual_rms, 3)),
        ("max force amplitude error [%]", lambda i: fmt(_max_fit(i, "amp_err_pct"), 3)),
        ("max force phase error [deg]", lambda i: fmt(_max_fit(i, "phase_err_deg"), 3)),
    ):
        cells = "".join(f"<td>{get(r.identification)}</td>" for r in results)
        quality.append(f'<tr><th class="l">{label}</th><td></td>{cells}{"<td></td>" if truth else ""}</tr>')
    return f"<table>{head}{''.join(body)}{''.join(quality)}</table>"


def _coherence_table(point) -> str:
    """The paper's Table 1: Omega/omega and the four gamma^2, for each LMS side by side
    (values below 0.9 are marked)."""
    tables = {lms: t for lms in LMS if (t := point.tables.get(lms)) is not None and t.gamma2 is not None}
    if not tables:
        return ""
    ref = next(iter(tables.values()))
    tables = {lms: t for lms, t in tables.items() if np.array_equal(t.orbit, ref.orbit)}
    ratio = ref.orbit / ref.spin
    dirs = whirl_direction(ref)
    head1 = '<tr><th class="l" rowspan="2">whirl</th><th rowspan="2">\u03a9/\u03c9</th>' + "".join(
        f'<th colspan="4">{_e(lms)} load cells</th>' for lms in tables) + "</tr>"
    head2 = "<tr>" + "".join(f"<th>\u03b3\u00b2 {_e(v)}</th>" for v in PAIR_LABELS.values()) * len(tables) + "</tr>"

    def cell(v: float) -> str:
        return f'<td class="err">{v:.3f}</td>' if v < 0.9 else f"<td>{v:.3f}</td>"

    rows = "".join(
        f'<tr><td class="l">{"forward" if dirs[i] > 0 else "backward"}</td><td>{ratio[i]:.3f}</td>'
        + "".join(cell(t.gamma2[i, c]) for t in tables.values() for c in range(4)) + "</tr>"
        for i in np.lexsort((ratio, -dirs))
    )
    return f"<h3>Coherence between motion and force signals</h3><table>{head1}{head2}{rows}</table>"


def _point_section(run, pr, out_dir: Path) -> str:
    p = pr.point
    s = p.settings
    h = [f'<h2 id="p{p.name}">Point {p.name}: {_e(s.label)}</h2>', _settings_table(s)]
    truth = true_constants(p)
    for lms in LMS:
        results = pr.results.get(lms, [])
        refused = [i for i in p.identifications if i.lms == lms and not i.ok]
        if not results and not refused:
            continue
        h.append(f"<h3>Coefficients, {lms} load cells</h3>")
        if results:
            h.append(_coefficient_table(results, truth))
        for i in refused:
            h.append(f'<p class="err">{_e(i.model)} {_e(i.freq_dep)} refused: {_e(i.error)}</p>')
    if pr.mismatches:
        h.append('<p class="err">Repeating the stored identifications gave different numbers:<br>'
                 + "<br>".join(_e(m) for m in pr.mismatches) + "</p>")
    h.append(_coherence_table(p))
    h += [_figure(png, out_dir) for png in pr.plots]
    return "\n".join(h)


def _figure(png: Path, out_dir: Path) -> str:
    rel = Path(png).relative_to(out_dir)
    return (f'<figure><img src="{_e(rel.as_posix())}" alt="{_e(rel.stem)}">'
            f'<figcaption class="muted">{_e(rel.name)}</figcaption></figure>')


def _points_table(report) -> str:
    """One row per reported point: its settings, linked to its section."""
    head = ("<tr><th>point</th><th class=\"l\">label</th><th>\u03c9 [rpm]</th><th>p<sub>r</sub> [MPa]</th>"
            "<th>\u03b2</th><th>\u03b5<sub>s</sub></th><th>\u03b5<sub>d</sub></th><th>models identified</th></tr>")
    rows = []
    for pr in report.points:
        s = pr.point.settings
        n = sum(len(v) for v in pr.results.values())
        rows.append(
            f'<tr><td><a href="#p{pr.point.name}">{pr.point.name}</a></td><td class="l">{_e(s.label)}</td>'
            f"<td>{s.spin_rpm:.0f}</td><td>{s.recess_pressure / 1e6:.4g}</td><td>{fmt(s.pressure_ratio)}</td>"
            f"<td>{fmt(s.static_eccentricity)}</td><td>{fmt(s.dynamic_eccentricity)}</td>"
            f"<td>{n} of {len(pr.point.identifications)}</td></tr>"
        )
    return f"<h2>Operating points</h2><table>{head}{''.join(rows)}</table>"


def render(report) -> str:
    run = report.run
    status = run.status if run.status in ("completed", "stopped", "aborted", "failed", "running") else "unknown"
    incomplete = [p.name for p in run.points if not p.complete]
    more = f", {len(incomplete)} incomplete ({', '.join(incomplete)})" if incomplete else ""
    head = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>orbitrig run {_e(run.directory.name)}</title><style>{CSS}</style></head><body>",
        f"<h1>orbitrig run <code>{_e(run.directory.name)}</code></h1>",
        f'<p>Status: <span class="status {status}">{_e(run.status)}</span> {_e(run.status_message)}</p>',
        "<table>",
        f'<tr><th class="l">matrix</th><td class="l">{_e(run.matrix_name)}</td></tr>',
        f'<tr><th class="l">mode</th><td class="l">{"simulator (--sim)" if run.sim else "rig"}</td></tr>',
        f'<tr><th class="l">created</th><td class="l">{_e(run.created)}</td></tr>',
        f'<tr><th class="l">software version</th><td class="l">{_e(run.software_version)}</td></tr>',
        f'<tr><th class="l">operating points</th><td class="l">{len(run.complete_points)} complete{more}</td></tr>',
        f'<tr><th class="l">report written</th><td class="l">{datetime.now(timezone.utc):%Y-%m-%d %H:%M:%S} UTC</td></tr>',
        "</table>",
    ]
    if report.points:
        head.append(_points_table(report))
    else:
        head.append('<p class="err">No complete operating point to report.</p>')
    head.append('<p class="muted">Units: K in MN/m, C in kN s/m, D in kg (SI at the source); '
                "\u00b1 one standard error of the regression. Higher-order terms multiply \u03a9^r with \u03a9 in rad/s.</p>")
    files = sorted(run.directory.glob("*.csv"))
    if files:
        head.append("<p>Tables: " + " \u00b7 ".join(
            f'<a href="../{_e(f.name)}">{_e(f.name)}</a>' for f in files) + "</p>")
    for name, text in (("rig configuration", run.rig_config), ("matrix configuration", run.matrix_config)):
        if text:
            head.append(f"<details><summary>{name}</summary><pre>{_e(text)}</pre></details>")
    if report.summary:
        head.append(_figure(report.summary, report.directory))
    body = [_point_section(run, pr, report.directory) for pr in report.points]
    return "\n".join(head + body + ["</body></html>"])


def write_html(report, path: Path) -> Path:
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(render(report), encoding="utf-8")
    tmp.replace(path)
    return path
