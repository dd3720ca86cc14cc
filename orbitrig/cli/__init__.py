"""The `orbitrig` command.

Each area registers its own sub-commands from a module ``orbitrig/cli/<area>.py``
exposing ``register(app: typer.Typer) -> None``. Those modules import their heavy
dependencies inside the command functions, so `orbitrig --help` stays fast and a
missing optional library breaks only the command that needs it.
"""

from __future__ import annotations

import importlib

import typer
import typer.main

from orbitrig.cli.help_text import command_group
from orbitrig.cli.threads import prompt_lock_handover
from rigthreads import one_blas_thread

one_blas_thread()  # before any command imports numpy (rigthreads)
prompt_lock_handover()  # the loop that polls the drives waits at most 1 ms for the interpreter

app = command_group(
    "Fluid-film bearing test rig: acquisition, drives, sweep, identification.",
    name="orbitrig",
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


def main() -> None:
    """Run the command line; what it could not write on standard output or error and no command
    handled ends here, the same for every command and for --help and --version (a reader gone
    away: exit 0, nothing said; a full disk, a quota, the file size limit: the error line naming
    standard output, exit 1, unbuffered too): orbitrig.cli.boundary."""
    from orbitrig.cli.boundary import run

    run(typer.main.get_command(app))


if __name__ == "__main__":
    main()
