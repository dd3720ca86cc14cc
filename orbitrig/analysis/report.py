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
- ``coherence_PPPP.png``: gamma^2 per frequency as a coloured table (Table 1, also in the page);
- ``signals_PPPP_FF_dir.png``: the paper's Figure 4 for one orbit frequency, (a) F_x and (b) F_y
  of both load measuring systems time-averaged, with their amplitude and phase difference, (c)
  F_x and (d) F_y of one raw revolution against the average; by default the lowest and highest orbit frequency of
  each whirl direction (``all_frequencies`` for every one);
- ``orbits_PPPP.png``: the measured x-y orbit of both probe planes, one panel per frequency;
- ``lms_PPPP.png``: strain-gauge vs piezoelectric forces and coefficients;
- ``summary.png`` (more than one point): one model's K and C at every point.

A repeated identification that differs from the stored one is reported
(``PointReport.mismatches``: a warning of the command and a note in the page).

All go to ``DIR/plots`` (or the folder ``out``, leaving the run untouched) with ``index.html`` (see orbitrig.analysis.report_html), each figure
as PNG (300 dpi, for the page), optionally beside PDF and SVG of the same name
(``ReportOptions.style``), and ``report.pdf``: the page's tables as text pages
(orbitrig.analysis.report_pages), then every figure, point by point, in one file for sharing
(orbitrig.analysis.report_pdf). Points are drawn by a pool of worker processes
(``workers``); a point whose inputs are unchanged keeps the figures an earlier report drew
(orbitrig.analysis.report_cache).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from orbitrig.analysis import plots as plots
from orbitrig.analysis.report_pdf import COMBINED_PDF, combine_pdf, run_info
from orbitrig.analysis.report_pages import table_pages
from orbitrig.analysis.report_pool import Progress, draw_points, settle
from orbitrig.analysis import plots_coefficients, plots_coherence, plots_derived, plots_forces, plots_lms, plots_signals
from orbitrig.analysis import plots_summary, report_cache
from orbitrig.analysis.quality import derived_basis, derived_k, true_impedance
from orbitrig.analysis.report_analysis import PREFERRED_MODELS, PointReport, analyse_point, fit_label, preferred
from orbitrig.analysis.signals import default_frequencies, read_block_signals
from orbitrig.analysis.rounding import orbit_frequency
from orbitrig.analysis.typeset import operating_point_math
from orbitrig.analysis.reduce import Reduced, own_truth
from orbitrig.load_systems import LMS, LoadSystem
from orbitrig.store.durable import remove
from orbitrig.store.fit_record import expanded_ks
from orbitrig.store.errors import storage_error
from orbitrig.store.reader import RunDirError, read_run
from orbitrig.store.stored_run import Frequency, Point, Run
from orbitrig.store.selection import select_points
from reduction.systematic import UncertaintyBasis
from reduction.whirl import Whirl

PLOTS_DIR = "plots"
#: figure kinds of a point (file name prefixes); `orbitrig report --figures` picks some
FIGURES = ("forces", "coefficients", "derived", "impedance", "coherence", "lms", "signals", "orbits")


@dataclass(frozen=True)
class ReportOptions:
    """What to draw: ``figures`` (kinds of FIGURES) and Figure 4 for every frequency or the default subset."""

    figures: frozenset[str] = frozenset(FIGURES)
    all_frequencies: bool = False
    style: plots.FigureStyle = plots.FigureStyle()


@dataclass
class Report:
    run: Run
    directory: Path  # DIR/plots
    points: list[PointReport]
    html: Path | None = None
    summary: Path | None = None  # summary.png, when more than one point
    skipped: list[str] = field(default_factory=list)  # points asked for and not reported, with why
    notes: list[str] = field(default_factory=list)  # points the run never completed (not asked for by number)
    pdf: Path | None = None  # report.pdf: the tables' pages, then every figure, in one file
    table_pages: int = 0  # how many pages of report.pdf are the tables' (before the figures)

    @property
    def plots(self) -> list[Path]:
        return [p for pr in self.points for p in pr.plots] + ([self.summary] if self.summary else [])


def signals_title(f: Frequency, where: str) -> str:
    """The title of block ``f``'s Figure 4, its orbit frequency as every figure states it
    (rounding.orbit_frequency) and ``where`` (the operating point) below."""
    return f"Force signals at {orbit_frequency(f.orbit_hz)} {Whirl.of(f.direction)} whirl (paper Fig. 4)\n{where}"


def _plot_signals(run: Run, pr: PointReport, out: Path, where: str, opts: ReportOptions) -> None:
    """Figure 4 per chosen frequency and the x-y orbits of every frequency of one point."""
    point = pr.point
    complete = sorted((f for f in point.frequencies if f.complete), key=lambda f: (-f.direction, f.orbit_hz))
    if not complete or not {"signals", "orbits"} & opts.figures:
        return
    chosen = complete if opts.all_frequencies else default_frequencies(point)
    chosen = chosen if "signals" in opts.figures else []
    blocks = {}
    for f in complete if "orbits" in opts.figures else chosen:
        try:
            blocks[f.name] = read_block_signals(run, point, f)
        except RunDirError as err:  # a damaged or old block: the other figures still get drawn
            pr.unreadable.append(f"signals of block {f.name} not drawn: {err}")
    chosen = [f for f in chosen if f.name in blocks]
    if not blocks:
        return
    for f in chosen:
        pr.plots.append(
            plots.save_figure(
                plots_signals.signals_figure(blocks[f.name], title=signals_title(f, where)),
                out / f"signals_{point.name}_{f.name}.png",
            )
        )
    if "orbits" not in opts.figures:
        return
    pr.plots.append(
        plots.save_figure(
            plots_signals.orbits_figure(
                list(blocks.values()),
                radius=point.settings.orbit_radius,
                title=f"Measured orbits (averaged displacements), both probe planes\n{where}",
            ),
            out / f"orbits_{point.name}.png",
        )
    )


def _plot_lms(pr: PointReport, lms: LoadSystem, out: Path, where: str, opts: ReportOptions) -> None:
    """Figure 5 with the adequacy verdicts, coefficients per model, derived quantities and,
    in simulator runs, the impedance against the true one, for one load measuring system."""
    point, table = pr.point, pr.point.tables[lms]
    results = pr.results.get(lms, [])
    verdict = {id(v.dependent): v.text for v in pr.verdicts.get(lms, [])}
    fitted = [_fitted(pr, r) for r in results]
    with_verdicts = [
        plots.Fitted(f.label + (f" \u2014 {verdict[id(r)]}" if id(r) in verdict else ""), f.identification, f.truth)
        for f, r in zip(fitted, results)
    ]
    if "forces" in opts.figures:
        pr.plots.append(
            plots_forces.forces_plot(
                out / f"forces_{point.name}_{lms}.png",
                table,
                with_verdicts,
                title=f"Measured and reproduced forces (paper Fig. 5), {lms} load cells\n{where}",
            )
        )
    for model in dict.fromkeys(r.model for r in results) if "coefficients" in opts.figures else ():
        group = [f for f, r in zip(fitted, results) if r.model == model]
        pr.plots.append(
            plots_coefficients.coefficients_plot(
                out / f"coefficients_{point.name}_{lms}_{model}.png",
                group,
                spin=table.spin,
                orbit=table.orbit,
                truth=point.truth,
                title=f"Rotordynamic coefficients, model {model}, {lms} load cells\n{where}",
            )
        )
    if pr.derived.get(lms) and "derived" in opts.figures:
        pr.plots.append(
            plots.save_figure(
                plots_derived.derived_figure(
                    [(fit_label(r), d, derived_basis(r)) for r, d in pr.derived[lms]],
                    spin=table.spin,
                    ks=[derived_k(r) for r, _ in pr.derived[lms]],
                    title=f"Derived quantities, {lms} load cells\n{where}",
                ),
                out / f"derived_{point.name}_{lms}.png",
            )
        )
    truth = true_impedance(point.truth)
    if truth is not None and fitted and "impedance" in opts.figures:
        pr.plots.append(
            plots.save_figure(
                plots_derived.impedance_figure(
                    fitted,
                    truth,
                    spin=table.spin,
                    orbit=table.orbit,
                    title=f"Identified impedance Z(\u03a9) against the {truth.label}, {lms} load cells\n{where}",
                ),
                out / f"impedance_{point.name}_{lms}.png",
            )
        )


def _plot_point(run: Run, pr: PointReport, out: Path, opts: ReportOptions) -> None:
    point = pr.point
    s = point.settings
    where = f"point {point.name}: {operating_point_math(s)}"
    _plot_signals(run, pr, out, where, opts)
    for lms in LMS:
        if point.tables.get(lms) is not None:
            _plot_lms(pr, lms, out, where, opts)
    coherence = plots_coherence.coherence_table(point.tables)
    if coherence is not None and "coherence" in opts.figures:
        pr.plots.append(
            plots.save_figure(
                plots_coherence.coherence_figure(
                    coherence,
                    title=f"Coherence between motion and force signals (paper Table 1)\n{where}",
                ),
                out / f"coherence_{point.name}.png",
            )
        )
    if all(lms in point.tables for lms in LMS) and "lms" in opts.figures:
        found = preferred(pr)
        pair = {lms: _fitted(pr, r) for lms, r in found.items()} if found else None  # U as the summary's
        pr.plots.append(
            plots_lms.lms_comparison_plot(
                out / f"lms_{point.name}.png",
                {lms: point.tables[lms] for lms in LMS},
                pair,
                title=f"Two load measuring systems: piezo and strain gauges\n{where}",
            )
        )


def _fitted(pr: PointReport, r: Reduced) -> plots.Fitted:
    """`r` to draw, with the covariance of its bands (PointReport.bands; the fit's own if none)."""
    b = pr.band(r)
    if b is None:
        return plots.Fitted(fit_label(r), r.identification, own_truth(r))
    ks = expanded_ks(r.stored or {}) if b.basis == UncertaintyBasis.COMBINED else None  # the table's k
    return plots.Fitted(fit_label(r), r.identification, own_truth(r), b.covariance, b.basis, ks)


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
    series = {lms: [(pr.point.index, _fitted(pr, found[lms])) for pr, found in chosen] for lms in LMS}
    truth = [(pr.point.index, pr.point.truth) for pr, _ in chosen if pr.point.truth]
    return plots_summary.summary_plot(
        report.directory / "summary.png",
        series,
        truth,
        model=spec[0],
        title=f"Constant coefficients ({spec[0]}) at every operating point, run {report.run.directory.name}",
        settings={pr.point.index: pr.point.settings for pr, _ in chosen},
    )


def _clear_point(out: Path, name: str) -> None:
    """Remove an earlier report's figures of point `name` (another subset or other kinds), in
    every format."""
    for kind in FIGURES:
        for fmt in plots.FigureFormat:
            for pattern in (f"{kind}_{name}.{fmt}", f"{kind}_{name}_*.{fmt}"):
                for old in out.glob(pattern):
                    remove(old)


def draw_point(run: Run, point: Point, out: Path, options: ReportOptions, drawn: Path | None = None) -> PointReport:
    """Analyse one point and draw its figures into `out` (in a worker process or here), or reuse
    those an earlier report drew there from the same inputs, or copy those recorded in `drawn`
    (the run's own DIR/plots, only read, when `out` is elsewhere; orbitrig.analysis.report_cache)."""
    pr = analyse_point(point)
    key = report_cache.point_key(point, options)
    formats = options.style.formats
    if report_cache.reuse(pr, out, key, formats) or (
        drawn is not None and drawn != out and report_cache.adopt(pr, drawn, out, key, formats)
    ):
        pr.reused = True
        return pr
    report_cache.forget(out, point.name)
    _clear_point(out, point.name)
    settle()
    _plot_point(run, pr, out, options)
    report_cache.remember(pr, out, key)
    return pr


def make_report(
    directory: str | Path,
    *,
    points: list[int] | None = None,
    options: ReportOptions = ReportOptions(),
    workers: int = 1,
    progress: Progress | None = None,
    run: Run | None = None,
    out: str | Path | None = None,
) -> Report:
    """Write ``DIR/plots/*.png`` (and .pdf, .svg when asked for), ``report.pdf`` and
    ``index.html``; return what was written. ``out``: another folder for all of them (made when
    missing; the run folder is then only read: the figures it holds of the same request are
    copied, not drawn again).

    ``points``: only these point indices (default: every complete one); ``options``: figure
    kinds, style, Figure 4 at every orbit frequency or the extremes of each direction. Figures
    of a kind not drawn are removed. Points asked for and not complete are named in `skipped`
    (orbitrig.store.selection); when none can be drawn (also a run without a complete point)
    nothing is touched and no folder made (``html`` None).
    ``workers`` processes draw the points; ``progress(done, total, figures)`` as each finishes;
    ``run``: DIR as already read. Raises RunDirError (not a run), StorageError (not writable)."""
    from orbitrig.analysis.report_html import write_html

    run = read_run(directory) if run is None else run
    selection = select_points(run, points)
    own = Path(directory) / PLOTS_DIR
    out = own if out is None else Path(out)
    if not selection.points:  # a mistyped --point, a run cut short: the page stays as it is (or is never made)
        return Report(run, out, [], skipped=selection.skipped, notes=selection.notes)
    try:
        out.mkdir(parents=out != own, exist_ok=True)
    except OSError as err:
        raise storage_error(out, "create the folder", err) from err
    plots.use_style(options.style)
    plots.use_source(run_info(run)["/Subject"])  # every figure file names its run (workers fork: theirs too)
    report = Report(run, out, [], skipped=selection.skipped, notes=selection.notes)
    report.points = draw_points(
        selection.points, lambda point: draw_point(run, point, out, options, own), workers=workers, progress=progress
    )
    for fmt in plots.FigureFormat:  # from an earlier report over other points
        remove(out / f"summary.{fmt}")
    report.summary = summary_plot_for(report)
    tables = table_pages(report.points, run)
    report.table_pages = tables.count
    report.pdf = combine_pdf(report.plots, out / COMBINED_PDF, run_info(run), tables)
    report.html = write_html(report, out / "index.html")
    return report
