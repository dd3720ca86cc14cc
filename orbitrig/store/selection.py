"""The operating points a command over a stored run (`export`, `report`) works on, and
every point it skips, named with the reason.

Asked for: the points given (``--point N``), or, without them, every point the run
committed (a commit record exists). A point asked for that is not complete (damaged,
missing, unreadable) is *skipped*: named, and the command exits non-zero. A point the
run never committed (a stopped or interrupted run), or never began to store, is only
*noted* when nobody asked for it by number.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

from orbitrig.store.index import NEVER_BEGUN, NEVER_COMPLETED
from orbitrig.store.layout import RunLayout, point_name
from orbitrig.store.stored_run import Point, Run


@dataclass
class Selection:
    """The complete points to work on (ascending), the skipped ones and the notes (messages)."""

    points: list[Point]
    skipped: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def skip(self, point: Point, reason: str) -> None:
        """Drop `point` from the selection (e.g. it has no orbit table), naming why."""
        self.points = [p for p in self.points if p.index != point.index]
        self.skipped.append(f"point {point.name} skipped: {reason}")

    def skip_tableless(self) -> None:
        """Drop each point that stores no orbit table, naming it (what `export` and `reduce`
        work on: the complete points with a table)."""
        for p in [p for p in self.points if not p.tables]:
            self.skip(p, "no orbit table stored")


def negative_point(wanted: Iterable[int] | None) -> str | None:
    """The problem of a point index asked for below 0 (``--point -1``: a usage mistake, not a
    point to skip), None when every one is 0 or more."""
    negative = [n for n in wanted or () if n < 0]
    return f"--point {negative[0]}: a point index is 0 or more" if negative else None


def unreadable_of(run: Run, name: str) -> list[str]:
    """The run's unreadable-file messages that belong to point directory `name`: those that begin
    with a file of DIR/points/`name` (a run directory named like a point, runs/0001, is no match)."""
    folder = str(RunLayout(run.directory).points / name)
    return [u for u in run.unreadable if u.startswith((f"{folder}/", f"{folder}."))]


def select_points(run: Run, wanted: Iterable[int] | None = None) -> Selection:
    """The complete points of `run` among `wanted` (None: all), and what is skipped; the run's
    warnings (a journal.jsonl missing) head the notes."""
    by_index = {p.index: p for p in run.points}
    if wanted is None:
        sel = Selection([p for p in run.points if p.complete], notes=list(run.warnings))
        for p in run.points:
            if p.complete:
                continue
            (sel.notes if p.problem == NEVER_COMPLETED else sel.skipped).append(
                f"point {p.name} {'not included' if p.problem == NEVER_COMPLETED else 'skipped'}: {p.problem}"
            )
        sel.notes += [f"point {point_name(i)} not included: {NEVER_BEGUN}" for i in run.unbegun]
        listed = {p.name for p in run.points}
        sel.skipped += [
            f"skipped: unreadable {u}" for u in run.unreadable if not any(f"/{name}/" in u for name in listed)
        ]
        return sel
    sel = Selection([], notes=list(run.warnings))
    for index in sorted(set(wanted)):
        found = by_index.get(index)
        if found is not None and found.complete:
            sel.points.append(found)
            continue
        name = point_name(index) if found is None else found.name
        why = (
            found.problem if found is not None else NEVER_BEGUN if index in run.unbegun else "no such point in the run"
        )
        details = unreadable_of(run, name)
        sel.skipped.append(f"point {name} skipped: {why}" + "".join(f"; unreadable {u}" for u in details))
    return sel
