"""The rig service's catalog feed: each completed point added to the campaign catalog.

`CatalogFeed.point_completed` is called on the service's event loop when a point's
results are stored, `CatalogFeed.run_ended` when the run's task has finished, whatever
its outcome (it adds the run's complete points again, now with the run's final status
and end time). A point's add reads the run's header, its journal and that point alone (not
the points before it again: a run's adds read each point once, not n^2/2 times). Each hands the work to the feed's own thread (reading the run back from
the run directory and writing the database may block: a table locked by another client,
a database server that does not answer) and returns at once; that thread adds one at a
time, in order of completion. A database that never answers holds that thread alone: not
the event loop's worker threads, which the service's broker connections (aiomqtt connects
in one), the run's identifications and its disk checks need; and not the process's exit
(a daemon thread: the service waits `finish` for it, bounded). Adds are idempotent
(orbitrig.catalog.store) and follow `catalog add`'s rule (orbitrig.catalog.run_add): the rows
of a point damaged since are deleted. A failure is logged and otherwise ignored: the catalog never
touches the drives or the run.
"""

from __future__ import annotations

import collections
import logging
import threading
import time
from pathlib import Path
from typing import Any

from orbitrig.catalog.errors import shown_url

log = logging.getLogger("orbitrig.service.catalog")

#: wall s the service's end waits for the catalog's adds in flight before it leaves without them
FINISH_S = 10.0


class CatalogFeed:
    def __init__(self, url: str):
        self.url = url
        self._catalog: Any = None  # a Catalog once the first point arrives
        self._todo: collections.deque[tuple[Path, int | None]] = collections.deque()  # (run dir, point)
        self._busy: tuple[Path, int | None] | None = None  # the add under way
        self._changed = threading.Condition()
        self._worker: threading.Thread | None = None  # started with the first add
        self.added = 0  # points added so far
        self.failed = 0  # points that could not be added

    def point_completed(self, run_dir: Path, point: int) -> None:
        """Add ``point`` of the run in ``run_dir`` to the catalog, in the feed's thread."""
        self._hand_over(Path(run_dir), int(point))

    def run_ended(self, run_dir: Path) -> None:
        """Add the complete points of the ended run in ``run_dir`` again (run_status, ended), in the feed's thread."""
        self._hand_over(Path(run_dir), None)

    def finish(self, timeout: float) -> list[Path]:
        """Wait up to ``timeout`` wall s for the adds handed over; the run directories of those not done."""
        deadline = time.monotonic() + timeout
        with self._changed:
            while self._left() and self._changed.wait(max(0.0, deadline - time.monotonic())):
                pass
            return list(dict.fromkeys(run_dir for run_dir, _ in self._left()))

    def _left(self) -> list[tuple[Path, int | None]]:
        return ([self._busy] if self._busy is not None else []) + list(self._todo)

    def _hand_over(self, run_dir: Path, point: int | None) -> None:
        with self._changed:
            self._todo.append((run_dir, point))
            self._changed.notify_all()
            if self._worker is None:
                self._worker = threading.Thread(target=self._work, name="orbitrig-catalog", daemon=True)
                self._worker.start()

    def _work(self) -> None:
        while True:
            with self._changed:
                while not self._todo:
                    self._changed.wait()
                self._busy = job = self._todo.popleft()
            try:
                self._add(*job)
            finally:
                with self._changed:
                    self._busy = None
                    self._changed.notify_all()

    def _add(self, run_dir: Path, point: int | None) -> None:
        """Add ``point`` of the run (None: all its complete points) by the rule of `catalog add`
        (orbitrig.catalog.run_add): the rows of points damaged since are deleted, and a run
        whose run.json cannot be read keeps its rows, the warning saying how many."""
        from orbitrig.catalog.run_add import kept_rows, run_add
        from orbitrig.store.layout import point_name
        from orbitrig.store.reader import RunDirError, read_run, read_run_points

        what = f"point {point}" if point is not None else "the ended run's points"
        try:
            try:  # read now: the run's status and end as they stand; a point: that point alone
                run = read_run(run_dir) if point is None else read_run_points(run_dir, [point])
            except RunDirError as err:
                kept = kept_rows(self._opened, run_dir)
                raise RunDirError(err.file, err.reason + (f"; {kept}" if kept else "")) from None
            todo = run_add(run, point)
            todo.write(self._opened())
            self.added += 1
            log.info("catalog: %s of %s added (run %s)", what, run_dir, run.status)
            if todo.damaged:
                damaged = ", ".join(point_name(i) for i in todo.damaged)
                log.warning("catalog: %s: damaged point(s) %s: their rows deleted", run_dir, damaged)
        except Exception as err:  # noqa: BLE001 - the catalog must never disturb the run
            self.failed += 1
            log.warning("catalog %s: %s of %s not added: %s", shown_url(self.url), what, run_dir, err)

    def _opened(self) -> Any:
        """The feed's catalog, opened at the first add."""
        from orbitrig.catalog.store import Catalog

        if self._catalog is None:
            self._catalog = Catalog(self.url)
        return self._catalog
