"""`orbitrig reduce DIR` and `orbitrig report DIR`: work on a stored run, no rig.

Exit status 0 on success, 2 for a missing or invalid DIR, a bad option, or a
model that no stored table can identify (the reason on standard error, as
`orbitrig identify`); 1 when the files cannot be written (read-only or full disk:
one line naming the file) or a point was skipped (damaged or, for `report --point`, not
complete: each named on standard error, the others reduced or drawn and written), and when
there is nothing to work on: no point asked for is complete (a run stopped before its first
point completed, a mistyped `report --point`), each point named with why, nothing written or
removed and no folder made, as `export` (orbitrig.cli.skipped.nothing_done).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, NoReturn, Optional

import typer

from orbitrig.cli.plain_table import OutputFormat, PlainTable, wrap
from orbitrig.cli.skipped import nothing_done, tell_skipped
from reduction.methods import Method


def _fail(message: str, code: int = 2) -> NoReturn:
    from orbitrig.cli.failure import fail

    fail(message, code)


#: what a command reading a run takes (reduce, report, export)
RUN_DIR_HELP = "Run directory written by `orbitrig sweep --out DIR`."
RunDir = Annotated[Path, typer.Argument(metavar="DIR", help=RUN_DIR_HELP)]
ModelOpt = Annotated[
    str,
    typer.Option("--model", help="kc7 (K, symmetric C) | kc8 (K, C) | kcd11 (K, C, symmetric D) | kcd12 (K, C, D)"),
]
FreqDepOpt = Annotated[
    str,
    typer.Option(
        "--freq-dep",
        help="coefficients' dependence on the orbit speed Omega (rad/s): none | power:M (K = K0 + Omega^M KM, likewise C, D) | power:m,n,p (exponents of K, C, D) | power:auto (best M in 1..4) | poly:R (polynomial to Omega^R)",
    ),
]
METHOD_HELP = "least squares: ols (ordinary) | wls (weighted) | tls (total) | iv (instrumental variables)"
MethodOpt = Annotated[Method, typer.Option("--method", help=METHOD_HELP)]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print one JSON object instead of the table (as --format json).")]
FormatOpt = Annotated[
    OutputFormat,
    typer.Option(
        "--format",
        help="text: a plain table of the constant terms in MN/m, kN s/m, kg, each \u00b1 its standard error (2 significant digits, the value to the same decimal), never cut, split to the terminal's width; csv: the same table in SI (N/m, N s/m, kg), each term followed by its _std, every number in full (the shortest decimal that reads back as the same double), the point as its index (3, as in the CSV files; the text writes 0003); json: one object with every result. Every format also writes DIR/reduce_*.csv",
    ),
]


def reduce_cmd(
    directory: RunDir,
    model: ModelOpt,
    freq_dep: FreqDepOpt = "none",
    method: MethodOpt = Method.OLS,
    as_json: JsonOpt = False,
    fmt: FormatOpt = OutputFormat.TEXT,
) -> None:
    """Identify again from a run's stored phasors, without the rig.

    Every complete point, both load measuring systems. Writes
    DIR/reduce_<model>_<freq-dep>_<method>.csv: the columns of coefficients.csv
    except the expanded uncertainties KEY_U (reduce makes no uncertainty budget;
    KEY_std is the fit's standard error; not_determined names the coefficients whose
    statistical expanded uncertainty k x KEY_std (k = 2 with u_*) exceeds their magnitude; warnings holds each fit's
    warnings joined with ' | '). Without --json each fit's warnings (reasons to
    distrust it: ill-conditioning, a bad chi2, weak excitation, bias) also go to
    standard error, one 'warning: point P LMS: ...' line each. The run's own
    results are left untouched. A damaged point is named on standard
    error and the exit status is 1, the others reduced and written (as export, report);
    a run without a complete point is reduced to nothing: each point named, no CSV, exit 1.
    """
    from orbitrig.errors import ReductionError
    from orbitrig.analysis.reduce import csv_path, reduce_run, write_csv
    from orbitrig.store.errors import StorageError
    from orbitrig.store.reader import RunDirError, read_run
    from reduction.identify import check_options

    try:
        check_options(model, freq_dep, method)  # bad usage (2) whatever the run holds
        run = read_run(directory)  # a directory: the CSV is written into it
    except (RunDirError, ReductionError) as err:
        _fail(str(err))
    selection = _reducible(run)
    try:
        rows = reduce_run(run, model, freq_dep, method, points=selection.points)
    except ReductionError as err:  # an option the check above let pass: usage (2)
        _fail(str(err))
    refused = [r for r in rows if r.identification is None]
    by_reason: dict[str, list[str]] = {}
    for r in refused:
        by_reason.setdefault(str(r.error), []).append(f"{r.point.name} {r.lms}")
    for reason, where in by_reason.items():
        typer.echo(f"{model} {freq_dep} refused at point {', '.join(where)}: {reason}", err=True)
    if len(refused) == len(rows):
        tell_skipped(selection.notes, selection.skipped)
        _fail(f"{model} {freq_dep} ({method}) cannot be identified from any stored table of {directory}")
    try:
        path = write_csv(csv_path(directory, model, freq_dep, method), rows, run.sim)
    except StorageError as err:
        _fail(str(err), 1)
    fmt = OutputFormat.JSON if as_json else fmt
    _print_reduce(directory, run, rows, path, fmt, f"{model} {freq_dep} ({method})")
    if fmt != OutputFormat.JSON:  # as identify: with --json the warnings are in the object
        for r in rows:
            for warning in r.identification.warnings if r.identification is not None else ():
                typer.echo(f"warning: point {r.point.name} {r.lms}: {warning}", err=True)
    if tell_skipped(selection.notes, selection.skipped):
        raise typer.Exit(1)


def _reducible(run):
    """The Selection of `run`'s complete points with an orbit table, as export and report: a
    damaged point (or one without a table) is named, exit 1; none: nothing to reduce, the one
    rule of export, report and reduce (orbitrig.cli.skipped.nothing_done, exit 1)."""
    from orbitrig.store.selection import select_points

    selection = select_points(run)
    selection.skip_tableless()
    if not selection.points:
        nothing_done("reduced", None, selection.notes, selection.skipped)
    return selection


def _print_reduce(directory: Path, run, rows, path: Path, fmt: OutputFormat, what: str) -> None:
    """The rows of `reduce` on standard output in `fmt`; `what` names the fit. A reader gone away
    (`| head`) ends the printing only; a full disk behind `> file` fails the command (exit 1)."""
    from orbitrig.cli.terminal import printing

    with printing():
        _print_reduce_rows(directory, run, rows, path, fmt, what)


def _print_reduce_rows(directory: Path, run, rows, path: Path, fmt: OutputFormat, what: str) -> None:
    from orbitrig.analysis.reduce import table_cells, table_legend

    if fmt == OutputFormat.JSON:
        out = {"run": str(directory), "csv": str(path), "status": run.status, "results": [r.to_dict() for r in rows]}
        typer.echo(json.dumps(out))
    elif fmt == OutputFormat.CSV:
        typer.echo(_plain(table_cells(rows, full=True)).csv())
    else:
        typer.echo(
            wrap(
                f"{what} from the stored orbit tables of {directory} "
                f"(run {run.status}, {len({r.point.index for r in rows})} complete point(s))"
            )
        )
        typer.echo(_plain(table_cells(rows)).text())
        typer.echo("\n" + "\n".join(wrap(line) for line in table_legend(rows)))
        typer.echo(f"written: {path}")


def _plain(cells: list[list[str]]) -> PlainTable:
    """The reduce table: point and lms as keys (left), numbers right."""
    table = PlainTable(key_columns=2)
    for i, name in enumerate(cells[0]):
        table.add_column(name, justify="left" if i < 2 else "right")
    for row in cells[1:]:
        table.add_row(*row)
    return table


PointOpt = Annotated[
    Optional[list[int]], typer.Option("--point", metavar="N", help="Only this operating point index (repeatable).")
]
AllFrequenciesOpt = Annotated[
    bool,
    typer.Option(
        "--all-frequencies",
        help="Force-signal figure (paper Fig. 4) for every orbit frequency, not only the lowest and highest of each whirl direction.",
    ),
]
FiguresOpt = Annotated[
    Optional[str],
    typer.Option(
        "--figures",
        metavar="KINDS",
        help="Only these figure kinds, comma-separated: forces, coefficients, derived, impedance, coherence, lms, signals, orbits (default: all). The tables of the page and report.pdf are always complete.",
    ),
]
WidthOpt = Annotated[
    str,
    typer.Option(
        "--width",
        help="Figure width: double (a journal's double column, 175 mm), single (its single column, 85 mm), "
        "inches (6.5) or millimetres (170mm). Placed at that width the figure prints its text at 7 to 7.5 pt.",
    ),
]
FormatsOpt = Annotated[
    str,
    typer.Option(
        "--formats",
        metavar="LIST",
        help="Files of each figure, comma-separated: png (300 dpi, for the page), pdf (vector; then report.pdf joins these), svg. Each vector format costs about as much time as the PNG.",
    ),
]
CoverageOpt = Annotated[
    float,
    typer.Option(
        "--coverage",
        min=0.5,
        max=5.0,
        help="Coverage factor k of the statistical-only bands and error bars (a run stored without a calibration budget) and of the measured phasors': +-k u (2: the expanded uncertainty U; 1: one standard uncertainty). Bands and error bars on the combined u take each coefficient's own k at 95.45 %, as the tables' U.",
    ),
]
WorkersOpt = Annotated[int, typer.Option("--workers", min=1, help="Processes drawing the points in parallel.")]
ReportOutOpt = Annotated[
    Optional[Path],
    typer.Option(
        "--out",
        metavar="FOLDER",
        help="Write the page, report.pdf and the figures into FOLDER (made when missing, outside DIR) instead of DIR/plots: a paper's figures (--width single, --figures, --formats) beside the operator's page, which stays as it is. DIR is only read: figures it holds of the same request are copied, not drawn again.",
    ),
]


def report_cmd(
    directory: RunDir,
    point: PointOpt = None,
    all_frequencies: AllFrequenciesOpt = False,
    figures: FiguresOpt = None,
    width: WidthOpt = "double",
    formats: FormatsOpt = "png",
    coverage: CoverageOpt = 2.0,
    workers: WorkersOpt = 2,
    out: ReportOutOpt = None,
) -> None:
    """Plots and an HTML page of a stored run, in DIR/plots (or --out FOLDER, DIR left untouched).

    Forces measured vs reproduced with the model-adequacy verdict (paper Fig. 5),
    coefficients against Omega/omega, derived quantities (effective damping, WFR,
    forward/backward dynamic stiffness), identified vs true impedance (simulator runs),
    coherence table, the two load measuring systems, force signals (paper Fig. 4) and
    the measured x-y orbits; DIR/plots/index.html shows them with the coefficients'
    intervals and uncertainties; DIR/plots/report.pdf has the page's tables, then every
    figure, in one file.
    Fit warnings and refusals go to standard error, with a progress bar on a terminal.
    A point asked for and not complete is named and the exit status is 1; when none can be
    drawn (also a run without a complete point) nothing is written (exit 1, as export, reduce).
    """
    from orbitrig.analysis.report import FIGURES, ReportOptions, make_report
    from orbitrig.cli.report_progress import ReportProgress
    from orbitrig.store.errors import StorageError
    from orbitrig.store.reader import RunDirError, read_run
    from orbitrig.store.selection import negative_point

    negative = negative_point(point)
    if negative:
        _fail(negative)
    if out is not None and out.resolve().is_relative_to(directory.resolve()):
        _fail(
            f"--out {out}: inside the run folder {directory}, which a report with --out leaves untouched (without --out the report goes to {directory / 'plots'})"
        )
    kinds = FIGURES if figures is None else tuple(k.strip() for k in figures.split(",") if k.strip())
    unknown = [k for k in kinds if k not in FIGURES]
    if unknown:
        _fail(f"--figures: unknown kind(s) {', '.join(unknown)}; choose from {', '.join(FIGURES)}")
    try:
        options = ReportOptions(
            figures=frozenset(kinds), all_frequencies=all_frequencies, style=_style(width, formats, coverage)
        )
        run = read_run(directory)  # once: the progress bar's total and the report's data
        total = len(point) if point else len(run.complete_points)
        with ReportProgress(total) as progress:
            report = make_report(
                directory, points=point, options=options, workers=workers, progress=progress, run=run, out=out
            )
    except (RunDirError, ValueError) as err:
        _fail(str(err))
    except StorageError as err:
        _fail(str(err), 1)
    _summary(directory, report, asked=bool(point))


def _summary(directory: Path, report, asked: bool) -> None:
    """What `report` made, its warnings on standard error; exit 1 when a point was skipped or
    none (`asked`: with --point) could be drawn."""
    from orbitrig.cli.terminal import printing
    from orbitrig.store.status import RunStatus

    run = report.run
    with printing():  # `| head`: the reader has what it wanted, the exit status stays
        typer.echo(
            f"run {run.status}: {len(run.complete_points)} complete point(s), "
            f"{len(run.points) - len(run.complete_points)} incomplete"
        )
        if run.status == RunStatus.RUNNING:  # the store says so until the run ends: also after a crash or kill -9
            typer.echo(
                f"(still running, or interrupted: `orbitrig sweep --resume {directory}` continues an "
                "interrupted run; add --sim if it was made on the simulator)"
            )
    for pr in report.points:
        for m in pr.mismatches:
            typer.echo(f"warning: point {pr.point.name}: {m}", err=True)
        for line in pr.fit_warnings():
            typer.echo(f"point {pr.point.name} {line}", err=True)
    if report.html is None:  # no point asked for could be drawn: the one rule of export, report and reduce
        nothing_done("drawn", report.directory, report.notes, report.skipped, asked=asked)
    with printing():
        typer.echo(f"{len(report.plots)} plot(s) in {report.directory}")
        if report.pdf:
            figures = " and all figures" if report.plots else " (no figure drawn)"
            typer.echo(f"the tables ({report.table_pages} pages){figures} in one file: {report.pdf}")
        typer.echo(f"open {report.html}")
    if tell_skipped(report.notes, report.skipped):
        raise typer.Exit(1)


def _style(width: str, formats: str, coverage: float):
    """The FigureStyle of --width, --formats and --coverage (exit 2 naming a bad value)."""
    from orbitrig.analysis.plots import COLUMN_WIDTHS, FigureFormat, FigureStyle

    try:
        mm = width.strip().lower().endswith("mm")
        inches = COLUMN_WIDTHS[width] if width in COLUMN_WIDTHS else float(width.strip()[: -2 if mm else None])
        inches = inches / 25.4 if mm else inches
    except ValueError:
        _fail(f"--width {width!r}: single, double, a width in inches or in millimetres (85mm)")
    if not 2.0 <= inches <= 20.0:
        _fail(f"--width {width}: {inches:.3g} in is outside 2..20 in")
    names = [f.strip().lower() for f in formats.split(",") if f.strip()]
    bad = [f for f in names if f not in set(FigureFormat)]
    if bad or FigureFormat.PNG not in names:
        _fail(f"--formats {formats!r}: png (needed by the page) and any of pdf, svg")
    return FigureStyle(width=inches, formats=tuple(FigureFormat(f) for f in dict.fromkeys(names)), coverage=coverage)


def register(app: typer.Typer) -> None:
    app.command("reduce")(reduce_cmd)
    app.command("report")(report_cmd)
