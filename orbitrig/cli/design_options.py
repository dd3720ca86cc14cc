"""The options of `orbitrig design` (typer Annotated aliases): speeds rpm, noise N and nm, radius micrometres."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from orbitrig.cli.config_help import RIG_CONFIG_HELP, matrix_names

from orbitrig.load_systems import LoadSystem
from rigunits import MICROMETRE

Model = Annotated[str, typer.Option("--model", help="kc7 | kc8 | kcd11 | kcd12")]
FreqDep = Annotated[str, typer.Option("--freq-dep", help="none | power:M | power:m,n,p | poly:R (as identify)")]
Spin = Annotated[float, typer.Option("--spin", help="Journal spin speed, rpm.")]
Ratios = Annotated[
    Optional[str],
    typer.Option("--ratios", help="Candidate orbit ratios |Omega|/omega, e.g. 0.2,0.5,1.2 (both directions)."),
]
Matrix = Annotated[
    Optional[str],
    typer.Option(
        "--matrix",
        help="Take the candidate list, directions and smallest orbit radius from this matrix (NAME from the "
        f"configuration's matrices/, as sweep --matrix takes it: {matrix_names()}; or FILE).",
    ),
]
NoiseFrom = Annotated[
    Optional[Path],
    typer.Option(
        "--noise-from",
        help="Run directory, or a run file itself (run.h5 or its h5 export, under any name): "
        "per-revolution noise (and prior coefficients) measured there.",
    ),
]
Lms = Annotated[LoadSystem, typer.Option("--lms", help="Load measuring system whose noise counts: piezo | strain.")]
ForceNoise = Annotated[
    Optional[float], typer.Option("--force-noise", help="Per-revolution force phasor noise, N (default 20).")
]
ProbeNoise = Annotated[
    Optional[float], typer.Option("--probe-noise", help="Per-revolution displacement phasor noise, nm (default 100).")
]
Radius = Annotated[
    Optional[float],
    typer.Option(
        "--radius", help=f"Orbit radius, {MICROMETRE} (default: the matrix's smallest, else 0.1 x clearance)."
    ),
]
Revolutions = Annotated[
    Optional[int],
    typer.Option(
        "--revolutions",
        help="Revolutions averaged per block (default: averaging.revolutions of the rig configuration).",
    ),
]
Target = Annotated[
    Optional[float],
    typer.Option(
        "--target",
        help="Worst relative standard error to reach, percent: propose ratios and revolutions per ratio that reach it in the least rig time.",
    ),
]
Match = Annotated[
    bool,
    typer.Option(
        "--match",
        help="Propose revolutions per ratio that give every coefficient at most the candidate's standard error in the least rig time.",
    ),
]
KeepTest = Annotated[
    bool,
    typer.Option(
        "--model-test/--no-model-test",
        help="With --match or --target: keep the adequacy test of the richest frequency-dependent model among --model with --freq-dep and the matrix's models (without one: poly:1 of the richest of them): enough ratios spread over the band, its errors at most the candidate's.",
    ),
]
PerDirection = Annotated[
    bool,
    typer.Option(
        "--per-direction",
        help="With --match or --target: let each whirl direction of each ratio be a block of its own (its own "
        "revolutions, or left out); the saved design gives each entry's direction ([orbit] whirl).",
    ),
]
KeepAway = Annotated[
    float, typer.Option("--keep-away", help="Propose no ratio closer than this to Omega/omega = 1 (runout).")
]
Save = Annotated[
    Optional[str],
    typer.Option(
        "--save",
        help="Write the proposal to designs/NAME.toml beside the rig configuration (a matrix uses it with "
        '[orbit] design = "NAME").',
    ),
]
RigPath = Annotated[Optional[Path], typer.Option("--config", help=RIG_CONFIG_HELP)]
AsJson = Annotated[bool, typer.Option("--json", help="Print one JSON object.")]
