"""`orbitrig report DIR`: PNG plots and an HTML page for a stored run.

For every complete operating point the sweep's stored identifications are
repeated from the stored orbit tables (``reduction.identify``; the objects
give ``reproduce`` and ``matrices(Omega)``, which the stored JSON cannot), and
drawn next to the measurements:

- ``forces_PPPP_<lms>.png``: measured vs reproduced force amplitude and phase
  (paper Figure 5), every identified model;
- ``coefficients_PPPP_<lms>_<model>.png``: K, C, D entries against Omega/omega
  (Figures 6 and 7), every frequency dependence of that model, with the true
  values in ``--sim`` runs;
- ``coherence_PPPP.png``: gamma^2 per frequency (Table 1, also a table in the page);
- ``lms_PPPP.png``: strain-gauge vs piezoelectric forces and coefficients;
- ``summary.png`` (more than one point): one model's K and C at every point.

A repeated identification that differs from the stored one is reported
(``PointReport.mismatches``: a warning of the command and a note in the page).

All go to ``DIR/plots`` with ``index.html`` (see orbitrig.analysis.report_html).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from orbitrig.analysis import plots as plots
from orbitrig.errors import ReductionError
from orbitrig.analysis.reduce import Reduced, reidentify
from orbitrig.config import LMS
from orbitrig.store.reader import Point, Run, read_run

PLOTS_DIR = "plots"
#: compared across the two load measuring systems, first one present wins
PREFERRED_MODELS = (("kcd11", "none"), ("kc8", "none"), ("kc7", "none"), ("kcd12", "none"))


@dataclass
class PointReport:
    """What the report shows of one operating point."""

    point: Point
    results: dict[str, list[Reduced]] = field(default_factory=dict)  # lms -> re-identified
    plots: list[Path] = field(default_factory=list)
    mismatches: list[str] = field(default_factory=list)  # stored vs repeated identification


@dataclass
class Report:
    run: Run
    directory: Path  # DIR/plots
    points: list[PointReport]
    html: Path | None = None
    summary: Path | None = None  # summary.png, when more than one point

    @property
    def plots(self) -> list[Path]:
        return [p for pr in self.points for p in pr.plots] + ([self.summary] if self.summary else [])


def fit_label(r: Reduced) -> str:
    """'kcd11 (11 coef.)', 'kcd11 power:1 (22 coef.)' - the paper's wording."""
    ident = r.identification
    fd = "" if r.freq_dep == "none" else f" {r.freq_dep}"
    if ident is not None and getattr(ident, "exponent", None) and r.freq_dep == "power:auto":
        fd = f" power:{ident.exponent} (auto)"
    n = f" ({ident.n_coefficients} coef.)" if ident is not None else ""
    method = "" if r.method == "ols" else f", {r.method}"
    return f"{r.model}{fd}{n}{method}"


def _compare(r: Reduced, stored: dict) -> list[str]:
    """Name coefficients where the repeated identification differs from the stored one."""
    if r.identification is None:
        return [f"{r.lms} {r.model} {r.freq_dep}: stored result, but repeating it was refused: {r.error}"]
    out = []
    coefs = stored.get("coefficients", {})
    new = r.identification.coefficients
    scale = {m: max((abs(v) for k, v in coefs.items() if k[0] == m), default=0.0) for m in "KCD"}
    for k, v in coefs.items():
        w = new.get(k)
        if w is None or not math.isclose(v, w, rel_tol=1e-6, abs_tol=1e-9 * scale.get(k[0], 0.0)):
            out.append(f"{r.lms} {r.model} {r.freq_dep}: {k} stored {v:.6g}, repeated {w}")
    return out


def analyse_point(point: Point) -> PointReport:
    """Repeat the sweep's identifications of one point (both LMS)."""
    pr = PointReport(point)
    for stored in point.identifications:
        if stored.lms not in point.tables or not stored.ok:
            continue
        try:
            r = reidentify(point, stored)
        except ReductionError as err:  # a stored spec this version of reduction rejects
            pr.mismatches.append(f"{stored.lms} {stored.model} {stored.freq_dep}: cannot be repeated: {err}")
            continue
        pr.mismatches += _compare(r, stored.result)
        if r.identification is not None:
            pr.results.setdefault(stored.lms, []).append(r)
    return pr


def _plot_point(pr: PointReport, out: Path) -> None:
    point = pr.point
    s = point.settings
    where = f"point {point.name}: {s.title()}"
    for lms in LMS:
        table = point.tables.get(lms)
        results = pr.results.get(lms, [])
        if table is None:
            continue
        fitted = [plots.Fitted(fit_label(r), r.identification) for r in results]
        pr.plots.append(plots.forces_plot(
            out / f"forces_{point.name}_{lms}.png", table, fitted,
            title=f"Measured and reproduced forces, {lms} load cells\n{where}",
        ))
        for model in dict.fromkeys(r.model for r in results):
            group = [f for f, r in zip(fitted, results) if r.model == model]
            pr.plots.append(plots.coefficients_plot(
                out / f"coefficients_{point.name}_{lms}_{model}.png", group,
                spin=table.spin, orbit=table.orbit, truth=point.truth,
                title=f"Rotordynamic coefficients, model {model}, {lms} load cells\n{where}",
            ))
    if any(t.gamma2 is not None for t in point.tables.values()):
        pr.plots.append(plots.coherence_plot(
            out / f"coherence_{point.name}.png", point.tables,
            title=f"Coherence between motion and force signals\n{where}",
        ))
    if all(lms in point.tables for lms in LMS):
        found = preferred(pr)
        pair = {lms: plots.Fitted(fit_label(r), r.identification) for lms, r in found.items()} if found else None
        pr.plots.append(plots.lms_comparison_plot(
            out / f"lms_{point.name}.png", {lms: point.tables[lms] for lms in LMS}, pair,
            title=f"Two load measuring systems: strain gauge vs piezoelectric\n{where}",
        ))


def preferred(pr: PointReport, model: tuple[str, str] | None = None) -> dict[str, Reduced]:
    """The first constant-coefficient model of PREFERRED_MODELS (or `model`) that was
    identified from both load measuring systems, per LMS; {} when there is none."""
    for spec in [model] if model else PREFERRED_MODELS:
        found = {lms: r for lms in LMS for r in pr.results.get(lms, []) if (r.model, r.freq_dep) == spec}
        if len(found) == len(LMS):
            return found
    return {}


def summary_plot_for(report: Report) -> Path | None:
    """summary.png: one model's K and C at every point, when there is more than one."""
    if len(report.points) < 2:
        return None
    for spec in PREFERRED_MODELS:
        chosen = [(pr, preferred(pr, spec)) for pr in report.points]
        chosen = [(pr, found) for pr, found in chosen if found]
        if len(chosen) >= 2:
            break
    else:
        return None
    series = {lms: [(pr.point.index, found[lms].identification) for pr, found in chosen] for lms in LMS}
    truth = [(pr.point.index, pr.point.truth) for pr, _ in chosen if pr.point.truth]
    return plots.summary_plot(
        report.directory / "summary.png", series, truth, model=spec[0],
        title=f"Constant coefficients ({spec[0]}) at every operating point, run {report.run.directory.name}",
    )


def make_report(directory: str | Path, *, points: list[int] | None = None) -> Report:
    """Write ``DIR/plots/*.png`` and ``DIR/plots/index.html``; return what was written.

    ``points`` restricts the plots to those operating point indices (all
    complete points by default). Raises RunDirError when DIR is not a run."""
    from orbitrig.analysis.report_html import write_html

    run = read_run(directory)
    chosen = [p for p in run.complete_points if points is None or p.index in points]
    if points is not None and len(chosen) < len(set(points)):
        missing = sorted(set(points) - {p.index for p in chosen})
        raise ValueError(f"{run.directory}: no complete operating point {missing}")
    out = Path(directory) / PLOTS_DIR
    out.mkdir(exist_ok=True)
    report = Report(run, out, [])
    for point in chosen:
        pr = analyse_point(point)
        _plot_point(pr, out)
        report.points.append(pr)
    stale = out / "summary.png"  # from an earlier report over other points
    stale.unlink(missing_ok=True)
    report.summary = summary_plot_for(report)
    report.html = write_html(report, out / "index.html")
    return report
