"""The `orbitrig` command.

Each area registers its own sub-commands from a module ``orbitrig/cli/<area>.py``
exposing ``register(app: typer.Typer) -> None``. Those modules import their heavy
dependencies inside the command functions, so `orbitrig --help` stays fast and a
missing optional library breaks only the command that needs it.
"""

from __future__ import annotations

import importlib

import typer
import typer.core

app = typer.Typer(
    name="orbitrig",
    help="Fluid-film bearing test rig: acquisition, drives, sweep, identification.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

_AREAS = (
    "identify",  # orbitrig identify
    "sim",  # orbitrig sim
    "acquire",  # orbitrig acquire
    "drives",  # orbitrig drives status|run|stop
    "sweep",  # orbitrig sweep
    "report",  # orbitrig reduce, orbitrig report
    "export",  # orbitrig export
    "serve",  # orbitrig serve
    "dashboard",  # orbitrig dashboard
    "design",  # orbitrig design
    "calibrate",  # orbitrig calibrate list|show|loads|runout
    "init",  # orbitrig init DIR
    "catalog",  # orbitrig catalog add|list|export
    "compare",  # orbitrig compare
)

for _area in _AREAS:
    importlib.import_module(f"orbitrig.cli.{_area}").register(app)


def _print_version(value: bool) -> None:
    if value:
        from orbitrig import __version__

        typer.echo(f"orbitrig {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(
        False, "--version", is_eager=True, callback=_print_version, help="Print the software version and exit."
    ),
) -> None:
    """Fluid-film bearing test rig: acquisition, drives, sweep, identification."""


@app.command("version")
def version() -> None:
    """Print the software version."""
    _print_version(True)


def _flags_without_type(command) -> None:
    """Typer's rich help (0.29, on its own copy of click) shows every option's type,
    flags included ("<bool>", also for --help), although a flag takes no value; an
    empty metavar leaves the type column blank. Walks ``command`` and its sub-commands."""
    for param in command.get_params(typer.Context(command)):  # includes the cached --help option
        if isinstance(param, typer.core.TyperOption) and param.is_flag:
            param.metavar = ""
    if isinstance(command, typer.core.TyperGroup):
        for sub in command.commands.values():
            _flags_without_type(sub)


def main() -> None:
    command = typer.main.get_command(app)
    _flags_without_type(command)
    command()


if __name__ == "__main__":
    main()
