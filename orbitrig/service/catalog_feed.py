"""The rig service's catalog feed: each completed point added to the campaign catalog.

`CatalogFeed.point_completed` is called on the service's event loop when a point's
results are stored, `CatalogFeed.run_ended` when the run's task has finished, whatever
its outcome (it adds the run's complete points again, now with the run's final status
and end time). Each hands the work to a worker thread (reading the run back from the
run directory and writing the database may block) and returns at once. Adds are
idempotent (orbitrig.catalog.store). A failure is logged and otherwise ignored: the
catalog never touches the drives or the run.
"""

from __future__ import annotations

import asyncio
import logging
import threading
from pathlib import Path
from typing import Any

log = logging.getLogger("orbitrig.service.catalog")


class CatalogFeed:
    def __init__(self, url: str):
        self.url = url
        self._catalog: Any = None  # a Catalog once the first point arrives
        self._lock = threading.Lock()  # one write at a time, in order of completion
        self.added = 0  # points added so far
        self.failed = 0  # points that could not be added

    def point_completed(self, run_dir: Path, point: int) -> None:
        """Add ``point`` of the run in ``run_dir`` to the catalog, in a worker thread."""
        asyncio.get_running_loop().run_in_executor(None, self._add, Path(run_dir), int(point))

    def run_ended(self, run_dir: Path) -> None:
        """Add the complete points of the ended run in ``run_dir`` again (run_status, ended), in a worker thread."""
        try:
            asyncio.get_running_loop().run_in_executor(None, self._add, Path(run_dir), None)
        except RuntimeError:  # the loop's executor is shut down (the service is leaving): here and now
            self._add(Path(run_dir), None)

    def _add(self, run_dir: Path, point: int | None) -> None:
        """Add ``point`` of the run (None: all its complete points)."""
        from orbitrig.catalog.rows import run_rows
        from orbitrig.catalog.store import Catalog
        from orbitrig.store.reader import read_run

        what = f"point {point}" if point is not None else "the ended run's points"
        with self._lock:
            try:
                run = read_run(run_dir)  # read now: the run's status and end as they stand
                points = [p for p in run.points if p.complete and point in (None, p.index)]
                if self._catalog is None:
                    self._catalog = Catalog(self.url)
                self._catalog.add(run_rows(run, points))
                self.added += 1
                log.info("catalog: %s of %s added (run %s)", what, run_dir, run.status)
            except Exception as err:  # noqa: BLE001 - the catalog must never disturb the run
                self.failed += 1
                log.warning("catalog %s: %s of %s not added: %s", self.url.split("@")[-1], what, run_dir, err)
