"""The points `export` and `reduce` work on are the complete points with an orbit table: one
owner (Selection.skip_tableless) drops a complete point whose tables were not read and names it
as skipped (the command then exits 1), the others kept in order."""

from __future__ import annotations

from orbitrig.store.reader import read_run
from orbitrig.store.selection import select_points


def test_a_complete_point_without_an_orbit_table_is_skipped_and_named(synthetic):
    run = read_run(synthetic)
    complete = [p for p in run.points if p.complete]
    assert len(complete) == 2 and all(p.tables for p in complete)
    complete[0].tables.clear()  # as if its tables were never stored
    selection = select_points(run)
    before = list(selection.skipped)
    selection.skip_tableless()
    assert [p.index for p in selection.points] == [complete[1].index]
    assert selection.skipped == [*before, f"point {complete[0].name} skipped: no orbit table stored"]
    selection.skip_tableless()  # nothing more to drop: said once
    assert len(selection.skipped) == len(before) + 1
