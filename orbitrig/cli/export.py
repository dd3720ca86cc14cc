"""`orbitrig export RUN`: a stored run's orbit tables and results as CSV, MATLAB, TDMS or HDF5.

Exit status 0 on success, 2 when RUN is not a run directory or the option is bad,
1 when the export cannot be written (disk full, permissions) or a point asked for
(every committed point, without --point) was skipped: each skipped point is named.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer


RunDir = Annotated[Path, typer.Argument(metavar="RUN", help="Run directory written by `orbitrig sweep --out DIR`.")]
Format = Annotated[
    str,
    typer.Option(
        "--format",
        help="csv (one orbit table per point and load system, coefficients.csv) | mat (MATLAB run.mat) | tdms (LabVIEW run.tdms) | h5 (the whole run in one run.h5 that GNU Octave loads too) | ross (ROSS BearingElement data, ross_bearings.json)",
    ),
]
Out = Annotated[Optional[Path], typer.Option("--out", help="Directory for the files (default RUN/export).")]
Points = Annotated[
    Optional[list[int]],
    typer.Option(
        "--point",
        metavar="N",
        help="Only this operating point index (repeatable; not with --format h5, the whole run).",
    ),
]
Fit = Annotated[
    str,
    typer.Option(
        "--fit", help="ross: the stored fit exported, LMS:MODEL:FREQ_DEP:METHOD (LMS '' = every load system)."
    ),
]


def register(app: typer.Typer) -> None:
    @app.command("export")
    def export_cmd(
        directory: RunDir,
        fmt: Format = "csv",
        out: Out = None,
        point: Points = None,
        fit: Fit = "piezo:kcd11:none:ols",
    ) -> None:
        """Export every complete operating point's orbit tables and results.

        A point asked for (every committed point, without --point) that is damaged or
        missing is named on standard error and the exit status is 1."""
        from orbitrig.store.errors import StorageError
        from orbitrig.store.export import FORMATS, export_run
        from orbitrig.store.reader import RunDirError

        if fmt not in (*FORMATS, "ross"):
            typer.echo(f"error: --format {fmt!r}: one of {', '.join(FORMATS)}, ross", err=True)
            raise typer.Exit(2)
        if point and fmt == "h5":
            typer.echo("error: --point does not apply to --format h5 (run.h5 holds the whole run)", err=True)
            raise typer.Exit(2)
        try:
            if fmt == "ross":
                typer.echo(str(_export_ross(directory, out, fit)))
                return
            done = export_run(directory, fmt, out, point)
        except RunDirError as err:
            typer.echo(f"error: {err}", err=True)
            raise typer.Exit(2) from None
        except StorageError as err:
            typer.echo(f"error: {err}", err=True)
            raise typer.Exit(1) from None
        for path in done.files:
            typer.echo(str(path))
        for line in done.selection.notes:
            typer.echo(line, err=True)
        for line in done.selection.skipped:
            typer.echo(f"error: {line}", err=True)
        if done.selection.skipped:
            raise typer.Exit(1)


def _export_ross(directory: Path, out: Path | None, fit: str) -> Path:
    """`--format ross`: RUN/export/ross_bearings.json (orbitrig.analysis.ross_export)."""
    from orbitrig.analysis.ross_export import export_ross
    from orbitrig.load_systems import LMS, LoadSystem
    from orbitrig.store.errors import storage_error
    from orbitrig.store.export import EXPORT_DIR
    from orbitrig.store.reader import read_run

    parts = fit.split(":")
    if len(parts) < 4 or not parts[1] or not parts[-1]:
        typer.echo(f"error: --fit {fit!r}: LMS:MODEL:FREQ_DEP:METHOD, e.g. piezo:kcd11:none:ols", err=True)
        raise typer.Exit(2)
    if parts[0] not in ("", *LMS):
        typer.echo(f"error: --fit {fit!r}: LMS is one of {', '.join(LMS)} or '' (every load system)", err=True)
        raise typer.Exit(2)
    lms = LoadSystem(parts[0]) if parts[0] else None
    model, freq_dep, method = parts[1], ":".join(parts[2:-1]), parts[-1]
    run = read_run(directory)
    target = out if out is not None else Path(directory) / EXPORT_DIR
    try:
        target.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise storage_error(target, "create the export directory", err) from err
    return export_ross(run, target, lms=lms, model=model, freq_dep=freq_dep, method=method)
