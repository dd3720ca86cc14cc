"""The help of the rig configuration option every command shares (``--config``; acquire's
``--rig``): where the configuration is found without it, in the order of orbitrig.config.home
(README "Where commands find the configuration"); and the shipped test matrices every --matrix
help names (`shipped_matrices`), read from their folder without loading orbitrig.config."""

from __future__ import annotations

from pathlib import Path

from orbitrig.shipped import PACKAGE, shipped_config

RIG_CONFIG_HELP = (
    "rig configuration TOML (default: rig.toml in $ORBITRIG_HOME, else in the current directory, "
    "else the shipped one; `orbitrig init DIR` writes one to edit)"
)


def shipped_matrices(package: Path = PACKAGE) -> tuple[str, ...]:
    """The shipped test matrices' names, sorted: every NAME.toml of matrices/ in the shipped
    configuration of the orbitrig `package` folder (orbitrig.shipped: ``orbitrig/data`` in an
    installed wheel, else ``config/`` of the source tree; a matrix added there is named without a
    line of code changed), without loading orbitrig.config, which loads numpy (every --help draws this)."""
    return tuple(sorted(p.stem for p in (shipped_config(package) / "matrices").glob("*.toml")))


def matrix_names() -> str:
    """The shipped matrices' names as a --matrix help lists them: 'demo, designed, eccentricity, paper'."""
    return ", ".join(shipped_matrices())
