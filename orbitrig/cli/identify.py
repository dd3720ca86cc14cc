"""`orbitrig identify TABLE.csv --model NAME [--freq-dep SPEC] [--method ...] [--solver ...] [--json]`.

Contract: docs/orbit-table.md. With --json exactly the result object on stdout (exit 0);
otherwise tables on stdout (text: numbers rounded for reading; csv: every number in full, the
shortest decimal that reads back as the same double) and the result's notes and warnings on stderr. The
table's warnings (a header column that looks like a misspelt known one) lead the result's.
Unidentifiable model or malformed table: exit 2, nothing on stdout, the reason on stderr.
"""

from __future__ import annotations

import json
import sys
import warnings
from pathlib import Path
from typing import Annotated, NoReturn

import typer

from orbitrig.analysis.rounding import number
from orbitrig.cli.plain_table import OutputFormat, PlainTable, render, wrap
from orbitrig.cli.report import METHOD_HELP, FreqDepOpt, ModelOpt
from rigunits import coefficient_unit, display_unit


def _fail(message: str) -> NoReturn:
    from orbitrig.cli.failure import fail

    fail(message)


def register(app: typer.Typer) -> None:
    @app.command("identify")
    def identify_cmd(
        table: Annotated[Path, typer.Argument(help="Orbit table CSV (columns: docs/orbit-table.md).")],
        model: ModelOpt,  # the model's options as reduce's and report's (one option, one help)
        freq_dep: FreqDepOpt = "none",
        method: str = typer.Option("ols", "--method", help=METHOD_HELP),
        solver: str = typer.Option("qr", "--solver", help="qr | svd | lu (least-squares solver)"),
        as_json: bool = typer.Option(False, "--json", help="Print the result as one JSON object (as --format json)."),
        fmt: OutputFormat = typer.Option(
            OutputFormat.TEXT,
            "--format",
            help="text: plain tables for reading, numbers rounded (values to 5, the rest to 4 significant digits), K, C, D in MN/m, kN s/m, kg (as reduce), never cut at any width; csv: the coefficient, force and covariance tables as CSV, in SI, every number in full (the shortest decimal that reads back as the same double); json: the result object",
        ),
    ) -> None:
        """Identify rotordynamic coefficients K, C, D from an orbit table."""
        import numpy as np

        from orbitrig.cli.terminal import printing
        from orbitrig.errors import OrbitrigError, TableError
        from reduction.identify import identify

        try:
            data, table_warnings = _read_table(table)
        except TableError as err:  # a table that cannot be read is not "malformed"
            _fail(str(err) if err.reason.startswith("cannot read") else f"malformed table: {err}")
        try:
            result = identify(data, model=model, freq_dep=freq_dep, method=method, solver=solver)
        except OrbitrigError as err:
            _fail(str(err))
        except (ArithmeticError, ValueError, np.linalg.LinAlgError) as err:  # the contract: exit 2, reason
            _fail(
                f"numerical failure of the {method} fit ({type(err).__name__}: {err}); "
                "check the table's values and units"
            )
        result.warnings[:0] = table_warnings
        as_json = as_json or fmt == OutputFormat.JSON
        with printing():  # `| head`: the reader has what it wanted, the exit status stays
            _write_json(result) if as_json else _print_readable(result, table, fmt)
        if not as_json:
            for note in result.notes:
                sys.stderr.write(f"note: {note}\n")
            for warning in result.warnings:
                sys.stderr.write(f"warning: {warning}\n")


def _read_table(path: Path):
    """The orbit table and the messages of its IgnoredColumnWarnings (other warnings pass on as usual)."""
    from orbitrig.errors import IgnoredColumnWarning
    from orbitrig.store.orbit_table import read_orbit_table

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", IgnoredColumnWarning)
        data = read_orbit_table(path)
    for w in caught:
        if not isinstance(w.message, IgnoredColumnWarning):
            warnings.showwarning(w.message, w.category, w.filename, w.lineno, w.file, w.line)
    return data, [str(w.message) for w in caught if isinstance(w.message, IgnoredColumnWarning)]


def _write_json(result, rows: int = 20000) -> None:
    """The result object on stdout; the per-row ``fit`` streamed in blocks of ``rows`` (a
    long table's rows never all become dicts at once)."""
    head = json.dumps(result.to_dict(fit=False), allow_nan=False)
    out = sys.stdout
    out.write(head[:-1] + ', "fit": [')
    for start in range(0, len(result.fit), rows):
        out.write((", " if start else "") + result.fit.json_rows(start, start + rows))
    out.write("]}\n")
    out.flush()


def _print_readable(result, path: Path, fmt: OutputFormat) -> None:
    """The fit's summary lines (text only) and its tables (coefficients, forces, covariance):
    text rounds the numbers for reading, CSV has every number in full."""
    import math

    import numpy as np

    from reduction.statistics import chi2_tail

    full = fmt == OutputFormat.CSV
    if fmt == OutputFormat.TEXT:
        fd = result.freq_dep + (f" (chosen M = {result.exponent})" if result.exponent is not None else "")
        typer.echo(wrap(f"{path}: model {result.model}, freq-dep {fd}, method {result.method}, solver {result.solver}"))
        distinct = len(np.unique(result.fit.columns["orbit_hz"]))  # a frequency run in both directions is 2 rows
        typer.echo(
            wrap(
                f"{result.n_coefficients} coefficients from {result.n_frequencies} rows ({distinct} distinct orbit "
                f"frequencies; minimum {result.min_frequencies} rows); condition number "
                f"{result.condition_number:.4g}; residual RMS {result.residual_rms:.4g} N; {result.dof} degrees of freedom"
            )
        )
        fit = f"AIC {number(result.aic)}, BIC {number(result.bic)}"
        if result.chi2 is not None:
            tail = chi2_tail(result.chi2, result.dof, math.nan if result.p_value is None else result.p_value)
            fit = f"chi2 {result.chi2:.4g} ({tail}), " + fit
        typer.echo(wrap(fit))
        for m, reason in sorted(result.skipped.items()):
            typer.echo(wrap(f"power:{m} skipped: {reason.splitlines()[0]}"))
        if result.covariance is None:
            typer.echo("no covariance: the fit gives none")
        typer.echo("")
    covariance = _covariance_table(result, full)
    tables = [_coefficient_table(result, full), _force_table(result, full)] + ([covariance] if covariance else [])
    typer.echo(render(tables, fmt))


def _unit(key: str, full: bool) -> tuple[str, float]:
    """Unit and scale (value in it = SI value x scale) of coefficient `key` in a table: SI in CSV
    (`full`), in text the unit a person reads, as ``reduce`` shows it (rigunits.display_unit: MN/m)."""
    return (coefficient_unit(key), 1.0) if full else display_unit(key)


def _coefficient_table(result, full: bool = False) -> PlainTable:
    """A row per coefficient: value, std error and interval in the row's ``unit`` (SI in CSV,
    MN/m, kN s/m, kg in text)."""
    t = PlainTable(title="Coefficients (SI, Omega in rad/s)" if full else "Coefficients (Omega in rad/s)")
    for col in ("coefficient", "value", "std error", "rel. std error [%]", "95 % interval", "unit"):
        t.add_column(col, justify="left" if col in ("coefficient", "unit") else "right")
    for key, v in result.coefficients.items():
        se = result.std_errors.get(key)
        rel = number(None if se is None or v == 0 else 100 * se / abs(v), full, 2)
        unit, k = _unit(key, full)
        ci = result.confidence_95.get(key)
        interval = number(None, full) if ci is None else f"[{number(ci[0] * k, full)}, {number(ci[1] * k, full)}]"
        t.add_row(key, number(v * k, full, 5), number(None if se is None else se * k, full), rel, interval, unit)
    return t


def _covariance_table(result, full: bool = False) -> PlainTable | None:
    """The covariance of the free coefficients (SI in CSV, the coefficients' text units in text),
    rows and columns in ``result.free``'s order; the entry of row a, column b is in unit(a) x
    unit(b) (each row's unit in the ``unit`` column, the columns' the same by symmetry). None when
    the fit gives no covariance."""
    if result.covariance is None:
        return None
    t = PlainTable(
        title=f"Covariance of the free coefficients ({'SI; ' if full else ''}row a, column b in unit(a) x unit(b), "
        "unit(a) in the unit column; a symmetric pair under its first key)",
        key_columns=2,
    )
    t.add_column("coefficient")
    t.add_column("unit")
    for name in result.free:
        t.add_column(name, justify="right")
    units = [_unit(name, full) for name in result.free]
    for name, (unit, ka), row in zip(result.free, units, result.covariance):
        t.add_row(name, unit, *(number(float(v) * ka * kb, full) for v, (_, kb) in zip(row, units)))
    return t


def _fit_columns() -> tuple[tuple[str, str], ...]:
    """The force table's columns: the contract's ``fit`` keys, each with its unit (pint parses
    them); imported here, not at the top: `orbitrig --help` does not load numpy."""
    from reduction.diagnostics import FIT_KEYS

    return tuple(zip(FIT_KEYS, ("Hz", "%", "deg", "%", "deg")))


def _force_table(result, full: bool = False) -> PlainTable:
    f = PlainTable(title="Reproduced vs measured force (reproduced minus measured)")
    columns = _fit_columns()
    for key, unit in columns:
        f.add_column(f"{key} [{unit}]", justify="right")
    for row in result.fit:
        f.add_row(*(number(row[key], full) for key, _ in columns))
    return f
