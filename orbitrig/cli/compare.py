"""`orbitrig compare`: catalog rows of one fit kind against an operating variable, repeated
runs overlaid with their chi2 consistency, predicted coefficients from a CSV (docs/catalog.md).

Exit status 0 on success, 2 for a bad option or predicted CSV or no matching rows, 1 when
the catalog cannot be read or the figure cannot be written.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Annotated, Optional

import typer

from orbitrig.cli.catalog import DbOption, RunsOption, WhereOption, catalog_guarded, open_catalog
from orbitrig.load_systems import LoadSystem
from reduction.methods import Method

DEFAULT_COEFFICIENTS = "Kxx,Kxy,Kyx,Kyy,Cxx,Cxy,Cyx,Cyy"
_RUNS_HELP = (
    "Run directories compared by themselves: their complete points read from their folders "
    "as `catalog add` reads them, no catalog made or read (--db, $ORBITRIG_CATALOG and --runs unused)."
)


def compare_cmd(
    runs: Annotated[Optional[list[Path]], typer.Argument(metavar="[RUN]...", help=_RUNS_HELP)] = None,
    against: Annotated[
        str,
        typer.Option("--against", help="x axis: static_eccentricity | dynamic_eccentricity | pressure_ratio | spin"),
    ] = "static_eccentricity",
    coefficients: Annotated[
        str, typer.Option("--coefficients", help="Comma-separated, e.g. Kxx,Cxx,Dxx.")
    ] = DEFAULT_COEFFICIENTS,
    lms: Annotated[LoadSystem, typer.Option("--lms", help="Load measuring system.")] = LoadSystem.PIEZO,
    model: Annotated[str, typer.Option("--model", help="Model of the compared fits.")] = "kcd11",
    freq_dep: Annotated[str, typer.Option("--freq-dep", help="Frequency dependence of the compared fits.")] = "none",
    method: Annotated[Method, typer.Option("--method", help="Estimation method of the compared fits.")] = Method.OLS,
    predicted: Annotated[
        Optional[Path], typer.Option("--predicted", help="CSV of predicted coefficients (docs/catalog.md).")
    ] = None,
    out: Annotated[Path, typer.Option("--out", help="Directory for compare.png and compare.pdf.")] = Path("."),
    where: WhereOption = "",
    db: DbOption = None,
    runs_dir: RunsOption = Path("runs"),
) -> None:
    """Plot coefficients with U bars across catalog rows (or those of the RUNs given) against one
    operating variable."""

    def action():
        from orbitrig.catalog.compare import Variable
        from orbitrig.catalog.compare_plot import compare_figure, compare_title, write_figure
        from orbitrig.catalog.errors import CatalogUsageError
        from orbitrig.catalog.predicted import predicted_lines, read_predicted
        from orbitrig.catalog.rows import COEFFICIENTS
        from orbitrig.cli.terminal import printing

        names = _checked(against, coefficients)
        table = read_predicted(predicted, Variable(against)) if predicted else None
        fit = f"lms = {lms} and model = {_literal('--model', model)} and freq_dep = {_literal('--freq-dep', freq_dep)}"
        fit += f" and method = {method} and ok = true"
        catalog, skipped = _runs_catalog(runs) if runs else (open_catalog(db, runs_dir), False)
        rows = catalog.rows(f"{fit} and {where}" if where.strip() else fit)
        if not rows:
            raise CatalogUsageError(no_rows(catalog, fit, f"{lms} {model} {freq_dep} {method}", where, bool(runs)))
        absent = [c for c in names if all(r.get(c) is None for r in rows)]
        if absent:  # else an empty panel, exit 0
            given = [c for c in COEFFICIENTS if any(r.get(c) is not None for r in rows)]
            raise CatalogUsageError(
                f"--coefficients {','.join(absent)}: no catalog row of {lms} {model} {freq_dep} {method} gives "
                f"{'it' if len(absent) == 1 else 'them'} (the model has none); its rows give {', '.join(given)}"
            )
        if table and not predicted_lines(table, rows, Variable(against)):
            typer.echo(
                f"--predicted {predicted}: no line's conditions are those of the plotted rows: none drawn", err=True
            )
        _tell_unknown_u(rows, names)
        title = compare_title(rows, lms, model, freq_dep, method, where)
        fig = compare_figure(rows, Variable(against), names, title=title, predicted=table)
        with printing():  # the figures written first; `| head`: the reader has what it wanted, the exit status stays
            typer.echo("\n".join(map(str, write_figure(fig, out))))
        if skipped:  # a damaged point of a RUN: exit 1, as export, report, reduce and catalog add
            raise typer.Exit(1)

    catalog_guarded(action)


def _checked(against: str, coefficients: str) -> list[str]:
    """The names of --coefficients; CatalogUsageError (exit 2) naming a bad --against or name."""
    from orbitrig.catalog.compare import Variable
    from orbitrig.catalog.errors import CatalogUsageError
    from orbitrig.catalog.rows import COEFFICIENTS

    if against not in tuple(Variable):
        raise CatalogUsageError(f"--against {against!r}: one of {', '.join(Variable)}")
    names = [c.strip() for c in coefficients.split(",") if c.strip()]
    if not names or any(c not in COEFFICIENTS for c in names):
        raise CatalogUsageError(f"--coefficients {coefficients!r}: names among {', '.join(COEFFICIENTS)}")
    return names


def _runs_catalog(runs: list[Path]):
    """A catalog in memory holding the rows `catalog add` would add of ``runs``: their complete
    points (the others named on standard error), and whether a point was skipped (damaged); a RUN
    that is no run is a RunDirError (exit 2)."""
    from orbitrig.catalog.run_add import run_add
    from orbitrig.catalog.store import Catalog
    from orbitrig.cli.skipped import tell_skipped
    from orbitrig.store.reader import read_run

    catalog, skipped = Catalog("sqlite://"), False
    for run in runs:
        todo = run_add(read_run(run))
        notes, damaged = todo.selection.notes, todo.selection.skipped
        skipped |= tell_skipped([f"{run}: {n}" for n in notes], [f"{run}: {s}" for s in damaged])
        todo.write(catalog)
    return catalog, skipped


def _tell_unknown_u(rows, names: list[str]) -> None:
    """Name on standard error each coefficient drawn at a point whose U is not known (a fit
    stored without it): drawn without a bar, which is no claim of a U of 0."""
    for name in names:
        unknown = [r for r in rows if r.get(name) is not None and r.get(f"{name}_U") is None]
        if unknown:
            where = ", ".join(f"{r['run_id']} point {r['point']}" for r in unknown)
            typer.echo(f"compare: {name} has no U at {where}: drawn without a bar", err=True)


#: at most this many distinct values of a column are listed when nothing matches
SHOWN_VALUES = 8


def no_rows(catalog, fit: str, kind: str, where: str, of_runs: bool = False) -> str:
    """Why compare has nothing to draw, with what the catalog (``of_runs``: the RUNs given) holds
    instead: the values of the columns ``where`` names among the rows of the fit kind, else the
    fit kinds there are."""
    from orbitrig.catalog.schema import ROW_COLUMNS

    text = f"no {'rows of the runs given' if of_runs else 'catalog rows'} for {kind}" + (
        f" where {where}" if where.strip() else ""
    )
    theirs = "their" if of_runs else "the catalog's"
    of_kind = catalog.rows(fit) if where.strip() else []
    if not of_kind:
        kinds = sorted({f"{r['lms']} {r['model']} {r['freq_dep']} {r['method']}" for r in catalog.rows("ok = true")})
        return f"{text}; {theirs} fits: {', '.join(kinds) or 'none'}"
    named = [c for c in ROW_COLUMNS if re.search(rf"(?<![\w.]){c}(?![\w.])", where)]
    held = []
    for column in named:
        values = sorted({_shown(r[column]) for r in of_kind})
        more = f", ... ({len(values)} values)" if len(values) > SHOWN_VALUES else ""
        held.append(f"{column} {', '.join(values[:SHOWN_VALUES])}{more}")
    return f"{text}; {theirs} {len(of_kind)} rows of that fit kind have {'; '.join(held)}"


def _literal(option: str, value: str) -> str:
    """`value` as a quoted text of the filter's grammar (orbitrig.catalog.where), whatever it holds:
    a name is compared as it is, never read as the filter's words."""
    from orbitrig.catalog.errors import CatalogUsageError

    if "'" not in value:
        return f"'{value}'"
    if '"' not in value:
        return f'"{value}"'
    raise CatalogUsageError(f"{option} {value!r}: a name holding both quote characters is no fit's name")


def _shown(value) -> str:
    return f"{value:.6g}" if isinstance(value, float) else str(value)


def register(app: typer.Typer) -> None:
    app.command("compare")(compare_cmd)
