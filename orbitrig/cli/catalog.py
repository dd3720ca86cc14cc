"""`orbitrig catalog add|list|export`: the campaign catalog (docs/catalog.md).

Exit status 0 on success, 2 for a bad option (--where outside the grammar, unknown
column, bad URL) or a RUN that is not a run directory, 1 when the catalog database
cannot be read or written.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

catalog_app = typer.Typer(
    help="The campaign catalog: one row per operating point and fit, across runs.", no_args_is_help=True
)

CATALOG_ENV = "ORBITRIG_CATALOG"
_DB_HELP = (
    f"Catalog database URL (sqlite:///FILE, postgresql://user@host/db; else ${CATALOG_ENV}; "
    "default: catalog.sqlite in the runs' directory)."
)
DbOption = Annotated[Optional[str], typer.Option("--db", envvar=CATALOG_ENV, help=_DB_HELP)]
RunsOption = Annotated[Path, typer.Option("--runs", help="Directory holding the runs (and the default catalog).")]
WhereOption = Annotated[str, typer.Option("--where", help="Filter: 'column op value [and ...]' (docs/catalog.md).")]


def _open(db: str | None, runs_dir: Path):
    from orbitrig.catalog.store import Catalog, default_url

    return Catalog(db or default_url(runs_dir))


def _guarded(action) -> None:
    """Run ``action`` with the CLI's one error boundary: messages, no tracebacks."""
    from orbitrig.catalog.errors import CatalogError, CatalogUsageError
    from orbitrig.store.errors import StorageError
    from orbitrig.store.reader import RunDirError

    try:
        action()
    except (CatalogUsageError, RunDirError) as err:
        typer.echo(f"error: {err}", err=True)
        raise typer.Exit(2) from None
    except (CatalogError, StorageError) as err:
        typer.echo(f"error: {err}", err=True)
        raise typer.Exit(1) from None


@catalog_app.command("add")
def add_cmd(
    runs: Annotated[list[Path], typer.Argument(metavar="RUN...", help="Run directories.")], db: DbOption = None
) -> None:
    """Add (or update) every complete point and fit of each RUN."""
    from orbitrig.catalog.rows import run_rows
    from orbitrig.store.reader import read_run

    def action():
        rows = [(run, run_rows(read_run(run))) for run in runs]
        catalog = _open(db, runs[0].resolve().parent)
        for run, run_rows_ in rows:
            typer.echo(f"{run}: {catalog.add(run_rows_)} rows")
        catalog.close()

    _guarded(action)


@catalog_app.command("list")
def list_cmd(
    where: WhereOption = "",
    db: DbOption = None,
    runs_dir: RunsOption = Path("runs"),
    columns: Annotated[str, typer.Option("--columns", help="Comma-separated columns to show.")] = "",
) -> None:
    """Show the rows matching --where as a table."""
    from orbitrig.catalog.errors import CatalogUsageError
    from orbitrig.catalog.render import LIST_COLUMNS, table
    from orbitrig.catalog.schema import ROW_COLUMNS

    def action():
        shown = tuple(c.strip() for c in columns.split(",") if c.strip()) or LIST_COLUMNS
        unknown = [c for c in shown if c not in ROW_COLUMNS]
        if unknown:
            raise CatalogUsageError(f"--columns: unknown {', '.join(unknown)}; columns: {', '.join(ROW_COLUMNS)}")
        typer.echo(table(_open(db, runs_dir).rows(where), shown))

    _guarded(action)


@catalog_app.command("export")
def export_cmd(
    fmt: Annotated[str, typer.Option("--format", help="csv | json")] = "csv",
    out: Annotated[Optional[Path], typer.Option("--out", help="File to write (default: standard output).")] = None,
    where: WhereOption = "",
    db: DbOption = None,
    runs_dir: RunsOption = Path("runs"),
) -> None:
    """Every column of the rows matching --where, as CSV or JSON."""
    from orbitrig.catalog.errors import CatalogUsageError
    from orbitrig.catalog.render import ExportFormat, render
    from orbitrig.store.durable import write_atomic

    def action():
        if fmt not in tuple(ExportFormat):
            raise CatalogUsageError(f"--format {fmt!r}: one of {', '.join(ExportFormat)}")
        data = render(_open(db, runs_dir).rows(where), ExportFormat(fmt))
        if out is None:
            typer.echo(data.decode(), nl=False)
        else:
            write_atomic(out, data)
            typer.echo(str(out))

    _guarded(action)


def register(app: typer.Typer) -> None:
    app.add_typer(catalog_app, name="catalog")
