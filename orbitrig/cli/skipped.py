"""What a command reading a run (export, report, reduce) did not take, on standard error: the
selection's notes (points the run never completed) as they are, and each point skipped
(damaged, or asked for and not complete) as an error (orbitrig.store.selection)."""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import typer


def tell_skipped(notes: Iterable[str], skipped: Sequence[str]) -> bool:
    """Print `notes`, then each of `skipped` as 'error: ...'; True when a point was skipped
    (the command then exits 1)."""
    for line in notes:
        typer.echo(line, err=True)
    for line in skipped:
        typer.echo(f"error: {line}", err=True)
    return bool(skipped)
