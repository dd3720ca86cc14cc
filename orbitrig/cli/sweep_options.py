"""The options of `orbitrig sweep` (typer Annotated aliases)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from orbitrig.cli.config_help import RIG_CONFIG_HELP, matrix_names

from orbitrig.cli.plain_table import OutputFormat
from orbitrig.cli.sim_options import MAX_SPEEDUP, SCENARIO_HELP

RunDir = Annotated[Optional[Path], typer.Argument(help="the run directory, as --out (`--resume DIR`)")]
Out = Annotated[Optional[Path], typer.Option("--out", help="run directory (run.h5, coefficients.csv, run.log)")]
Sim = Annotated[bool, typer.Option("--sim", help="run on the built-in simulator over loopback protocols")]
Config = Annotated[
    Optional[Path],
    typer.Option(
        "--config",
        help=RIG_CONFIG_HELP,
    ),
]
Matrix = Annotated[
    Optional[str],
    typer.Option(
        "--matrix",
        metavar="NAME|FILE",
        help=f"test matrix: a TOML file, or a name from the configuration's matrices/ ({matrix_names()}); "
        "required on the rig, --sim defaults to matrices/demo.toml",
    ),
]
Resume = Annotated[bool, typer.Option("--resume", help="continue the run in --out from its first incomplete point")]
DryRun = Annotated[
    bool,
    typer.Option(
        "--dry-run",
        help="print the plan's totals, the predicted uncertainty of each model and one line per operating point; touches no hardware",
    ),
]
Steps = Annotated[
    bool, typer.Option("--steps", help="with --dry-run: also every step with its start time and estimated duration (s)")
]
Format = Annotated[
    OutputFormat,
    typer.Option(
        "--format",
        help="the closing table of coefficients: text (plain, each value to the decimal of its U, U to 2 significant digits, never cut, split to the terminal's width), csv (the same tables) or json; every number in full, SI: DIR/run.h5 (orbitrig.open_run; `orbitrig export` fits.csv)",
    ),
]
Speedup = Annotated[
    float, typer.Option("--speedup", min=0.01, max=MAX_SPEEDUP, help="simulator time / wall time (--sim only)")
]
#: --sim-config of the commands that start a simulator with --sim (sweep, serve, calibrate)
SimConfig = Annotated[
    Optional[Path], typer.Option("--sim-config", metavar="NAME|FILE", help=f"{SCENARIO_HELP}; --sim only")
]


def operator_given(operator: Optional[str]) -> Optional[str]:
    """--operator (sweep, calibrate): as given, or None (not given: the login name); an empty or
    blank name is a usage error (exit 2) naming the option, not the login name recorded silently."""
    if operator is not None and not operator.strip():
        raise typer.BadParameter("an empty operator name: give who it is, or leave --operator out for the login name")
    return operator


Operator = Annotated[
    Optional[str],
    typer.Option(
        "--operator",
        help="who runs the sweep, recorded in the run (default: the login name)",
        callback=operator_given,
    ),
]
DrawFigures = Annotated[
    bool,
    typer.Option(
        "--draw-figures/--no-draw-figures",
        help="draw each completed point's report figures in a process at the lowest CPU priority, so `orbitrig report` afterwards reuses them",
    ),
]
