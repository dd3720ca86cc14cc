"""The rig service's catalog feed: each completed point added to the campaign catalog.

`CatalogFeed.point_completed` is called on the service's event loop when a point's
results are stored; it hands the work to a worker thread (reading the point back from
the run directory and writing the database may block) and returns at once. Adds are
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

    def _add(self, run_dir: Path, point: int) -> None:
        from orbitrig.catalog.rows import run_rows
        from orbitrig.catalog.store import Catalog
        from orbitrig.store.reader import read_run

        with self._lock:
            try:
                run = read_run(run_dir)
                points = [p for p in run.points if p.index == point and p.complete]
                if self._catalog is None:
                    self._catalog = Catalog(self.url)
                self._catalog.add(run_rows(run, points))
                self.added += 1
                log.info("catalog: point %d of %s added", point, run_dir)
            except Exception as err:  # noqa: BLE001 - the catalog must never disturb the run
                self.failed += 1
                log.warning("catalog %s: point %d of %s not added: %s", self.url.split("@")[-1], point, run_dir, err)
