"""The run's index, rebuilt from what is on disk: which points are complete, which are not.

A point is complete when its commit record (``complete.json``) parses and every file it
names has the recorded size and SHA-256 digest. Anything else (no commit record, a file
missing, torn or altered) makes the point incomplete; `problem` says why.
"""

from __future__ import annotations

from typing import Any
import json
from dataclasses import dataclass

from orbitrig.store.durable import digest
from orbitrig.store.errors import StorageError
from orbitrig.store.layout import COMMIT_FILE, POINT_FILE, RunLayout


#: the problem of a point whose run never committed it (stopped, killed, still running)
NEVER_COMPLETED = "never completed (no commit record)"
#: the problem of a point whose folder exists but whose settings record was never written
#: (the run was cut between the two): nothing of it is stored, nothing is damaged
NEVER_BEGUN = "never begun (no settings record)"


@dataclass(frozen=True)
class PointState:
    index: int
    complete: bool
    problem: str = ""  # why it is not complete ("" when complete)


def commit_record(layout: RunLayout, index: int, known: dict[str, dict[str, Any]] | None = None) -> dict[str, Any]:
    """The content of a new commit record: every file of the point with its size and digest
    (`known`: name -> {"size", "sha256"} of files this process wrote; the others are read)."""
    d = layout.point_dir(index)
    files = {}
    for p in sorted(d.iterdir()):
        if p.is_file() and p.name != COMMIT_FILE and not p.name.endswith(".tmp"):
            entry = (known or {}).get(p.name)
            if entry is None or entry["size"] != p.stat().st_size:
                size, sha = digest(p)
                entry = {"size": size, "sha256": sha}
            files[p.name] = entry
    return {"point": index, "files": files}


def point_state(layout: RunLayout, index: int) -> PointState:
    """Check one point directory against its commit record."""
    path = layout.commit_file(index)
    if not path.is_file():
        return PointState(index, False, NEVER_COMPLETED)
    try:
        rec = json.loads(path.read_bytes())
        files = rec["files"]
        if not isinstance(files, dict) or not all(isinstance(want, dict) for want in files.values()):
            raise ValueError("'files' is not an object of {size, sha256} objects")
        if rec["point"] != index or POINT_FILE not in files:
            raise ValueError("names another point or lacks point.json")
    except (OSError, ValueError, KeyError, TypeError, RecursionError) as err:
        return PointState(index, False, f"commit record unreadable ({type(err).__name__}: {err})")
    d = layout.point_dir(index)
    for name, want in files.items():
        p = d / name
        if not p.is_file():
            return PointState(index, False, f"{name} is missing")
        try:
            size, sha = digest(p)
        except StorageError as err:
            return PointState(index, False, str(err))
        if (size, sha) != (want.get("size"), want.get("sha256")):
            return PointState(index, False, f"{name} is damaged ({size} bytes, digest differs from the commit record)")
    return PointState(index, True)


def scan(layout: RunLayout) -> list[PointState]:
    """The state of every point directory, ascending index (every file of every point read and hashed)."""
    return [point_state(layout, i) for i in layout.point_indexes()]


class CompletePoints:
    """Which points of a run being written are complete: the one record of it in the writing
    process (orbitrig.store.writer.RunStore). `verify` checks every point against its commit
    record (every file read and hashed: when a run is resumed and before run.h5 is consolidated);
    `add` records a point the store has just committed (its digests are those of the bytes it
    wrote), so a commit never reads the points before it again. Not verified yet (a store just
    opened), `points` verifies first."""

    def __init__(self, layout: RunLayout):
        self.layout = layout
        self._known: set[int] | None = None  # None: not verified in this process yet
        self._states: list[PointState] | None = None  # the last verification, until a point changes

    def verify(self) -> tuple[list[PointState], list[PointState]]:
        """Every point checked in full: (the state of each point folder, and those recorded
        complete here that are not any more: a file altered, truncated or removed since)."""
        states = scan(self.layout)
        now = {st.index: st for st in states}
        lost = [now.get(i, PointState(i, False, "its folder is missing")) for i in sorted(self._known or ())]
        self._known = {st.index for st in states if st.complete}
        self._states = states
        return states, [st for st in lost if not st.complete]

    def verified(self) -> list[PointState]:
        """The state of every point folder as this process verified it last (the resume's one check,
        which `points` made when the sweep asked whether every point is complete, under the run's
        lock), else verified now; once taken it is not given again (the caller moves points)."""
        states = self._states if self._states is not None else self.verify()[0]
        self._states = None
        return states

    def add(self, index: int) -> None:
        """Point `index` was just committed by this process."""
        if self._known is None:
            self.verify()
        assert self._known is not None
        self._known.add(index)
        self._states = None  # the folders changed since

    def points(self) -> list[int]:
        """The complete points, ascending (verified in full once, then as recorded here)."""
        if self._known is None:
            self.verify()
        return sorted(self._known or ())
