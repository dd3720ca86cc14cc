"""The one rule of adding a run to the catalog, for `orbitrig catalog add` and the service's
feed (orbitrig.service.catalog_feed): what an add writes and what it deletes, and what the
catalog keeps of a run whose run.json cannot be read.

An add of a run (or of one of its points) writes the rows of its complete points and, in
the same transaction, first deletes the rows the catalog holds of those points and of every
point damaged since (complete once, not now: a point the run never committed is left as
it is). The catalog then says what the run folder says now.

A run whose run.json cannot be read (or whose folder is gone) is not touched: its rows from
an earlier add are kept, not removed (a file being copied or a share that is down is no
reason to lose a campaign's rows), and the caller says so with `kept_rows`: how many rows
of which run, and that they stay until the run is added again.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from orbitrig.catalog.errors import CatalogError
from orbitrig.catalog.rows import run_rows
from orbitrig.store.index import NEVER_COMPLETED
from orbitrig.store.selection import Selection, select_points
from orbitrig.store.stored_run import Run

if TYPE_CHECKING:
    from orbitrig.catalog.store import Catalog


@dataclass
class RunAdd:
    """One add of a run: its ``rows`` and the ``points`` whose rows it replaces (those added
    and those damaged since; `Catalog.add` deletes them first), with the selection's words."""

    run_id: str
    rows: list[dict[str, Any]]
    points: list[int]
    selection: Selection
    damaged: list[int] = field(default_factory=list)

    def write(self, catalog: Catalog) -> int:
        """Write this add into ``catalog`` (one transaction); the number of rows written."""
        return catalog.add(self.rows, self.run_id, self.points)


def run_add(run: Run, point: int | None = None) -> RunAdd:
    """The add of ``run``: all its points, or only ``point`` (the service's feed, as each
    point completes)."""
    sel = select_points(run)
    if point is not None:
        sel.points = [p for p in sel.points if p.index == point]
    damaged = [
        p.index for p in run.points if not p.complete and p.problem != NEVER_COMPLETED and point in (None, p.index)
    ]
    added = [p.index for p in sel.points]
    return RunAdd(run.run_id, run_rows(run, sel.points), sorted(added + damaged), sel, damaged)


def kept_rows(opened: Callable[[], Catalog | None], run_dir: Path) -> str:
    """What the catalog ``opened()`` gives keeps of the run that was read from ``run_dir`` and
    cannot be now: '' when it holds no row of it (or there is no catalog), else the words saying
    how many rows of which run stay; a catalog that cannot be asked is said so (the run's own
    problem is still told, not hidden behind the database's)."""
    try:
        catalog = opened()
        held = catalog.held_at(str(Path(run_dir).resolve())) if catalog is not None else {}
    except CatalogError as err:
        return f"what the catalog keeps of it is not known ({err})"
    if not held:
        return ""
    runs = ", ".join(f"{n} rows of run {run_id}" for run_id, n in held.items())
    return f"the catalog keeps its {runs} from an earlier add (not removed; add the run again once it can be read)"
