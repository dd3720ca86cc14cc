"""The `orbitrig` command.

Each area registers its own sub-commands from a module ``orbitrig/cli/<area>.py``
exposing ``register(app: typer.Typer) -> None``. Those modules import their heavy
dependencies inside the command functions, so `orbitrig --help` stays fast and a
missing optional library breaks only the command that needs it.
"""

from __future__ import annotations

import importlib

import typer

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
)

for _area in _AREAS:
    importlib.import_module(f"orbitrig.cli.{_area}").register(app)


@app.command("version")
def version() -> None:
    """Print the software version."""
    from orbitrig import __version__

    typer.echo(__version__)


def main() -> None:
    app()


if __name__ == "__main__":
    main()
