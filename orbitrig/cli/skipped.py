"""What a command reading a run (export, report, reduce) did not take, on standard error: the
selection's notes (points the run never completed) as they are, and each point skipped
(damaged, or asked for and not complete) as an error (orbitrig.store.selection).

The one rule of the three for a run with nothing to work on (no point asked for is complete:
a mistyped --point, a run stopped before its first point completed): `nothing_done` names
every point and why, writes and removes nothing, says so and exits 1, the status of a
command that could not do its work; bad usage (a bad option, DIR no run) stays 2. `catalog add`
of several runs says the same of each such run (`nothing_why`), adds the others and exits 1.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import NoReturn

import typer

from orbitrig.cli.failure import fail, say_error


def tell_skipped(notes: Iterable[str], skipped: Sequence[str]) -> bool:
    """Print `notes`, then each of `skipped` as 'error: ...'; True when a point was skipped
    (the command then exits 1)."""
    for line in notes:
        typer.echo(line, err=True)
    for line in skipped:
        say_error(line)
    return bool(skipped)


def nothing_done(
    done: str, target: Path | None, notes: Iterable[str], skipped: Sequence[str], asked: bool = False
) -> NoReturn:
    """No point asked for (`asked`: with --point) is complete: each point with why on standard
    error, then on standard output whether `target` (the output folder; None: the command prints
    no such line) was left as it was or never made, and 'error: nothing <done>: why'; exit 1."""
    noted = list(notes)
    tell_skipped(noted, skipped)
    if target is not None:
        kept = f"{target} left as it was" if target.exists() else f"no folder written ({target} not made)"
        typer.echo(f"nothing {done}: {kept}")
    fail(f"nothing {done}: {nothing_why(noted, skipped, asked)}", 1)


def nothing_why(notes: Sequence[str], skipped: Sequence[str], asked: bool = False) -> str:
    """Why a run gives nothing to work on, after its points were named (`nothing_done`'s words;
    `catalog add` says them per run, going on with its other runs)."""
    if asked:
        return "no operating point asked for with --point is complete (named above)"
    if [n for n in notes if not n.startswith("warning: ")] or skipped:  # a point named, not only the run's warnings
        return "the run has no complete operating point (each is named above with why)"
    return "the run stores no operating point"
