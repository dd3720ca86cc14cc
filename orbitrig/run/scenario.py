"""A simulated rig's scenario as a run records it (plain data: the command line's dry run reads
it without loading the rig's I/O)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Scenario:
    """A simulated rig's scenario as recorded in the run: its name (the file given, or the
    default: config/sim.toml) and its configuration text (TOML)."""

    name: str
    text: str = ""
