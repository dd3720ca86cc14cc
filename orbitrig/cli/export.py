"""`orbitrig export RUN`: a stored run's orbit tables and results as CSV, MATLAB, TDMS or HDF5.

Exit status 0 on success, 2 when RUN is not a run directory or an option is bad (a negative
--point, a --fit with another format than ross; also a ross --fit that no selected point
stores: the fits there are are named), 1
when the export cannot be written (disk full, permissions) or a point asked for (every
committed point, without --point) was skipped, for ross also a point without the fit or at a
speed its test condition already has: each one is named. When no point asked for can be exported
(a mistyped --point, or a run without a complete operating point) nothing is written or removed
(no folder made; an earlier export stays as it was), the reason is an error line and the exit
status is 1, as for `report` and `reduce` (orbitrig.cli.skipped.nothing_done); --format h5 holds
the whole run, complete or not.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from orbitrig.cli.report import RUN_DIR_HELP
from orbitrig.cli.skipped import nothing_done, tell_skipped
from orbitrig.errors import OrbitrigError

RunDir = Annotated[Path, typer.Argument(metavar="RUN", help=RUN_DIR_HELP)]
Format = Annotated[
    str,
    typer.Option(
        "--format",
        help="csv (one orbit table per point and load system, coefficients.csv) | mat (MATLAB run.mat) | tdms (LabVIEW run.tdms) | h5 (the whole run in one run.h5 that GNU Octave loads too) | ross (ROSS BearingElement data over rotor speed, ross_bearings.json)",
    ),
]
Out = Annotated[Optional[Path], typer.Option("--out", help="Directory for the files (default RUN/export).")]
Points = Annotated[
    Optional[list[int]],
    typer.Option(
        "--point",
        metavar="N",
        help="Only this operating point index, 0 or more (repeatable; not with --format h5, the whole run).",
    ),
]
#: the fit `--format ross` exports without --fit
DEFAULT_FIT = "piezo:kcd11:none:ols"
Fit = Annotated[
    Optional[str],
    typer.Option(
        "--fit",
        help="ross: the stored fit exported, LMS:MODEL:FREQ_DEP:METHOD (LMS '' = every load system), at each "
        "point's spin (synchronous whirl; else the constant fit); a fit no point stores exits 2, a point without "
        f"it is named and the exit status is 1 (default {DEFAULT_FIT}; with another format exits 2).",
    ),
]


class ExportOptionError(OrbitrigError):
    """A bad option of `orbitrig export` (exit status 2)."""


def register(app: typer.Typer) -> None:
    @app.command("export")
    def export_cmd(
        directory: RunDir,
        fmt: Format = "csv",
        out: Out = None,
        point: Points = None,
        fit: Fit = None,
    ) -> None:
        """Export every complete operating point's orbit tables and results.

        A point asked for (every committed point, without --point) that is damaged or
        missing, or (ross) lacks the fit, is named on standard error and the exit status is 1;
        a --fit that no point stores exits 2, naming the fits there are. When no point asked
        for can be exported (also a run without a complete point) nothing is written, no
        folder made, an earlier export stays as it was (exit 1, as report and reduce)."""
        from orbitrig.analysis.ross_export import FitNotStoredError
        from orbitrig.cli.failure import fail
        from orbitrig.cli.terminal import printing
        from orbitrig.store.errors import StorageError
        from orbitrig.store.export import EXPORT_DIR
        from orbitrig.store.reader import RunDirError

        try:
            files, selection = _export(directory, fmt, out, point, fit)
        except (RunDirError, ExportOptionError, FitNotStoredError) as err:
            fail(str(err), 2)
        except StorageError as err:
            fail(str(err), 1)
        if not files:  # nothing to export: the one rule of export, report and reduce (exit 1)
            target = out if out is not None else directory / EXPORT_DIR
            nothing_done("exported", target, selection.notes, selection.skipped, asked=bool(point))
        with printing():  # `| head`: the reader has what it wanted, the exit status stays
            for path in files:
                typer.echo(str(path))
        if tell_skipped(selection.notes, selection.skipped):
            raise typer.Exit(1)


def _export(directory: Path, word: str, out: Path | None, point: list[int] | None, fit: str | None):
    """The files written and the selection (orbitrig.store.selection.Selection)."""
    from orbitrig.store.export import ExportFormat, export_run
    from orbitrig.store.selection import negative_point

    if word not in set(ExportFormat):
        raise ExportOptionError(f"--format {word!r}: one of {', '.join(ExportFormat)}")
    fmt = ExportFormat(word)
    if point and fmt is ExportFormat.H5:
        raise ExportOptionError("--point does not apply to --format h5 (run.h5 holds the whole run)")
    negative = negative_point(point)
    if negative:
        raise ExportOptionError(negative)
    if fmt is ExportFormat.ROSS:
        return _export_ross(directory, out, point, fit or DEFAULT_FIT)
    if fit is not None:
        raise ExportOptionError(
            f"--fit {fit!r} applies to --format ross only (--format {fmt} exports every stored fit)"
        )
    exported = export_run(directory, fmt, out, point)
    return exported.files, exported.selection


def _fit_spec(fit: str):
    """``--fit LMS:MODEL:FREQ_DEP:METHOD`` (FREQ_DEP may hold ':', e.g. power:1)."""
    from orbitrig.analysis.ross_export import FitSpec
    from orbitrig.load_systems import LMS, LoadSystem
    from reduction.methods import METHODS, Method

    parts = fit.split(":")
    if len(parts) < 4 or not parts[1] or not parts[-1]:
        raise ExportOptionError(f"--fit {fit!r}: LMS:MODEL:FREQ_DEP:METHOD, e.g. piezo:kcd11:none:ols")
    if parts[0] not in ("", *LMS):
        raise ExportOptionError(f"--fit {fit!r}: LMS is one of {', '.join(LMS)} or '' (every load system)")
    if parts[-1] not in METHODS:
        raise ExportOptionError(f"--fit {fit!r}: METHOD is one of {', '.join(METHODS)}")
    lms = LoadSystem(parts[0]) if parts[0] else None
    return FitSpec(lms, parts[1], ":".join(parts[2:-1]), Method(parts[-1]))


def _export_ross(directory: Path, out: Path | None, point: list[int] | None, fit: str):
    """`--format ross`: RUN/export/ross_bearings.json (orbitrig.analysis.ross_export); the
    files written and the selection (none written when no point asked for is complete)."""
    from orbitrig.analysis.ross_export import export_ross
    from orbitrig.store.errors import storage_error
    from orbitrig.store.export import EXPORT_DIR
    from orbitrig.store.reader import read_run
    from orbitrig.store.selection import select_points

    spec = _fit_spec(fit)
    run = read_run(directory)
    selection = select_points(run, point)
    if not selection.points:  # an earlier export stays as it was
        return [], selection
    target = out if out is not None else Path(directory) / EXPORT_DIR
    try:
        target.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise storage_error(target, "create the export directory", err) from err
    done = export_ross(run, target, spec, selection)
    return [done.path], done.selection
