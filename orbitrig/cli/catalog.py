"""`orbitrig catalog add|list|export`: the campaign catalog (docs/catalog.md).

Exit status 0 on success, 2 for a bad option (--where outside the grammar, unknown
column, bad URL) or (`add`) when no RUN was added and one is not a run directory or its
run.json cannot be read (each such RUN is named, the others added: exit 1 when some were), 1
when the catalog database cannot be read or written (`list`, `export`, `compare`: also when the default SQLite
file does not exist; they never create it), the --out file cannot be written, or (`add`)
a point of a RUN was skipped: each damaged point is named on standard error, as
`orbitrig export` names it, and the others are added; or (`add`) a RUN has no complete point:
it adds nothing, each of its points named with why, as `export`, `report` and `reduce` do for
a run with nothing to work on (orbitrig.cli.skipped), and the other RUNs are added.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Optional

import typer

from orbitrig.cli.failure import fail, say_error
from orbitrig.cli.help_text import command_group

if TYPE_CHECKING:
    from orbitrig.catalog.store import Catalog

catalog_app = command_group(
    "The campaign catalog: one row per operating point and fit, across runs.", no_args_is_help=True
)

CATALOG_ENV = "ORBITRIG_CATALOG"
_DB_HELP = (
    f"Catalog database URL (sqlite:///FILE, postgresql://user@host/db; else ${CATALOG_ENV}; "
    "default: catalog.sqlite in the runs' directory)."
)
DbOption = Annotated[Optional[str], typer.Option("--db", envvar=CATALOG_ENV, help=_DB_HELP)]
RunsOption = Annotated[Path, typer.Option("--runs", help="Directory holding the runs (and the default catalog).")]
WhereOption = Annotated[str, typer.Option("--where", help="Filter: 'column op value [and ...]' (docs/catalog.md).")]


def open_catalog(db: str | None, runs_dir: Path, create: bool = False):
    """The catalog at --db, else catalog.sqlite in `runs_dir`; `create`: make a missing SQLite
    file (only `add` does: reading one that is not there is a CatalogError naming it)."""
    from orbitrig.catalog.errors import CatalogMissingError
    from orbitrig.catalog.store import Catalog, default_url

    try:
        return Catalog(db or default_url(runs_dir), create=create)
    except CatalogMissingError as err:
        here = Path("catalog.sqlite")  # `catalog add */` run among the runs puts it here
        if db is None and here.is_file() and here.resolve() != (runs_dir / here).resolve():
            raise CatalogMissingError(f"{err}; this folder holds one, {here.resolve()}: give --runs .") from None
        raise


#: what the [catalog] extra installs: without one of them, catalog and compare name the extra
CATALOG_MODULES = frozenset({"sqlalchemy", "psycopg", "psycopg2"})


def catalog_guarded(action) -> None:
    """Run ``action`` with the CLI's one error boundary: messages, no tracebacks (exit 2 for a
    bad option, a run that is not one or a missing [catalog] extra; 1 for a catalog or storage
    failure)."""
    from orbitrig.catalog.errors import CatalogError, CatalogUsageError
    from orbitrig.store.errors import StorageError
    from orbitrig.store.reader import RunDirError

    try:
        action()
    except ModuleNotFoundError as err:
        if (err.name or "").split(".")[0] not in CATALOG_MODULES:
            raise
        fail(
            f"the catalog needs {err.name}, which is not installed: pip install -e '.[catalog]'"
            " in orbitrig's source tree (SQLAlchemy and the PostgreSQL driver)",
            2,
        )
    except (CatalogUsageError, RunDirError) as err:
        fail(str(err), 2)
    except (CatalogError, StorageError) as err:
        fail(str(err), 1)


@catalog_app.command("add")
def add_cmd(
    runs: Annotated[list[Path], typer.Argument(metavar="RUN...", help="Run directories.")], db: DbOption = None
) -> None:
    """Add (or update) every complete point and fit of each RUN.

    A damaged point (or one whose pieces cannot be read) is named on standard error and the
    exit status is 1, as `orbitrig export` does; the run's other points are added. A RUN with
    no complete point adds nothing (each point named with why, then 'error: RUN: nothing
    added: ...'), the other RUNs are added, and the exit status is 1; when no RUN has one, no
    catalog file is made. A RUN that is no run directory, or whose run.json cannot be read, is
    named with why ('error: RUN: not added: ...') and the other RUNs are added; the exit status
    is then 1, or 2 when no RUN was added. A RUN the catalog cannot take (a database locked
    or down) is named with the database's error ('error: RUN: not added: catalog ...') and the
    other RUNs are tried; the exit status is 1. Adding a RUN again first deletes its rows of the points it adds and
    of the points damaged since: the catalog then says what the run folder says now."""
    from orbitrig.store.reader import RunDirError, read_run

    def action():
        from orbitrig.catalog.errors import CatalogError
        from orbitrig.catalog.run_add import kept_rows
        from orbitrig.catalog.store import check_url, default_url

        url = db or default_url(runs[0].resolve().parent)
        check_url(url, "--db")  # bad usage (2) whatever the runs hold
        adding = _Adding(url)
        failed, refused = False, False
        for run in runs:
            try:
                data = read_run(run)
            except RunDirError as err:  # named, and the other RUNs added all the same
                why = err.reason if Path(err.file) == run else str(err)
                kept = kept_rows(lambda: adding.open(create=False), run)  # its rows of an earlier add stay
                say_error(f"{run}: not added: {why}" + (f"; {kept}" if kept else ""))
                refused = True
                continue
            try:
                failed |= adding.add(run, data)
            except CatalogError as err:  # the RUN named; the others tried all the same
                say_error(f"{run}: not added: {err}")
                failed = True
        adding.close()
        if refused or failed:
            raise typer.Exit(2 if refused and not adding.added else 1)

    catalog_guarded(action)


@catalog_app.command("list")
def list_cmd(
    where: WhereOption = "",
    db: DbOption = None,
    runs_dir: RunsOption = Path("runs"),
    columns: Annotated[str, typer.Option("--columns", help="Comma-separated columns to show.")] = "",
) -> None:
    """Show the rows matching --where as a table."""

    def action():
        from orbitrig.catalog.errors import CatalogUsageError
        from orbitrig.catalog.render import LIST_COLUMNS, table, units_note
        from orbitrig.catalog.schema import ROW_COLUMNS
        from orbitrig.cli.terminal import printing

        shown = tuple(c.strip() for c in columns.split(",") if c.strip()) or LIST_COLUMNS
        unknown = [c for c in shown if c not in ROW_COLUMNS]
        if unknown:
            raise CatalogUsageError(f"--columns: unknown {', '.join(unknown)}; columns: {', '.join(ROW_COLUMNS)}")
        with printing():  # `| head`: the reader has what it wanted, the units note follows
            typer.echo(table(open_catalog(db, runs_dir).rows(where), shown))
        if note := units_note(shown):
            typer.echo(note, err=True)  # for the reader; standard output stays the table alone

    catalog_guarded(action)


@catalog_app.command("export")
def export_cmd(
    fmt: Annotated[str, typer.Option("--format", help="csv | json")] = "csv",
    out: Annotated[Optional[Path], typer.Option("--out", help="File to write (default: standard output).")] = None,
    where: WhereOption = "",
    db: DbOption = None,
    runs_dir: RunsOption = Path("runs"),
) -> None:
    """Every column of the rows matching --where, as CSV or JSON."""
    from orbitrig.store.durable import write_atomic

    def action():
        from orbitrig.catalog.errors import CatalogUsageError
        from orbitrig.catalog.render import ExportFormat, render

        if fmt not in tuple(ExportFormat):
            raise CatalogUsageError(f"--format {fmt!r}: one of {', '.join(ExportFormat)}")
        data = render(open_catalog(db, runs_dir).rows(where), ExportFormat(fmt))
        if out is None:
            typer.echo(data.decode(), nl=False)  # last: orbitrig.cli.boundary
            return
        _check_folder(out)
        write_atomic(out, data)
        typer.echo(str(out))

    catalog_guarded(action)


class _Adding:
    """`catalog add`, run by run, into the catalog at `url`, opened when first needed."""

    def __init__(self, url: str):
        self.url = url
        self.catalog: Catalog | None = None
        self.added = 0  # RUNs whose rows were added

    def add(self, run: Path, data) -> bool:
        """Add the complete points of `data` (read from `run`), replacing the rows the catalog
        holds of them and deleting those of its damaged points (orbitrig.catalog.run_add, the
        rule the service's feed follows too); True when a point was skipped or nothing could
        be added (the command then exits 1)."""
        from orbitrig.catalog.run_add import run_add
        from orbitrig.cli.skipped import nothing_why, tell_skipped

        todo = run_add(data)
        sel = todo.selection
        notes, skipped = [f"{run}: {n}" for n in sel.notes], [f"{run}: {s}" for s in sel.skipped]
        if not sel.points:  # nothing to add: the rule of export, report and reduce, run by run
            tell_skipped(notes, skipped)
            say_error(f"{run}: nothing added: {nothing_why(notes, skipped)}")
            catalog = self.open(create=False) if todo.damaged else None
            if catalog is not None:
                todo.write(catalog)  # its rows of points damaged since deleted
            return True
        catalog = self.open(create=True)
        assert catalog is not None  # created when missing
        typer.echo(f"{run}: {todo.write(catalog)} rows")
        self.added += 1
        return tell_skipped(notes, skipped)

    def open(self, create: bool) -> Catalog | None:
        """The catalog, opened once (`create` False: None when its SQLite file is not there)."""
        from orbitrig.catalog.errors import CatalogMissingError

        if self.catalog is None:
            try:
                self.catalog = open_catalog(self.url, Path("."), create=create)
            except CatalogMissingError:
                return None
        return self.catalog

    def close(self) -> None:
        if self.catalog is not None:
            self.catalog.close()


def _check_folder(out: Path) -> None:
    """A StorageError naming `out` when its folder is missing or a path on the way is a file,
    naming that path (the atomic writer names only the temporary file it could not create)."""
    from orbitrig.store.errors import StorageError

    there = next(folder for folder in (*out.parents, Path("/")) if folder.exists())
    if not there.is_dir():
        raise StorageError(out, f"cannot write: {there} is not a directory")
    if there != out.parent:
        raise StorageError(out, f"cannot write: no folder {out.parent}")


def register(app: typer.Typer) -> None:
    app.add_typer(catalog_app, name="catalog")
