"""The last run in the service's runs folder as the store recorded it: the ``last_run`` of the
service's first status (``service ready``, docs/protocols/mqtt.md), so that a subscriber or a
dashboard that comes after a restart sees how that run ended and where it is.

The store owns what is said: the run's id (run.json), its status, the status's message and
time (the journal's last ``status`` line). The last run is the one whose journal was written
last (a resumed run counts by its latest session); journals of the same modification time (a
share that keeps whole seconds, or the file system's clock tick: two runs ended within it) are
told apart by the time of their last status, then by folder name; one of them that cannot be read
(a damaged line, a read error) is left out with a warning naming the file (and line), the others
compared. Nothing is guessed for a run
whose status still says ``running`` (a kill left it so): it is said as stored, with no end time."""

from __future__ import annotations

import asyncio
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from orbitrig.run.room_check import on_daemon_thread
from orbitrig.store.consolidate import read_header
from orbitrig.store.errors import RunDirError, StorageError
from orbitrig.store.identity import header_identity
from orbitrig.store.journal import Journal, read_journal
from orbitrig.store.layout import HEADER, JOURNAL, RunLayout
from orbitrig.store.status import RunStatus

log = logging.getLogger(__name__)
#: wall s the service waits for its runs folder at its start (a network share that does not answer)
READ_S = 5.0


@dataclass(frozen=True)
class LastRun:
    """What the store holds of the last run: its id, stored status, the status's message, its
    folder (absolute) and the time its final status was recorded (None while it says running)."""

    run_id: str
    outcome: RunStatus
    message: str
    folder: Path
    ended_at: str | None

    def payload(self) -> dict[str, Any]:
        """The status's ``last_run`` object (docs/protocols/mqtt.md)."""
        return {
            "run_id": self.run_id,
            "outcome": self.outcome,
            "message": self.message,
            "folder": str(self.folder),
            "ended_at": self.ended_at,
        }


def read_last_run(runs_dir: Path) -> LastRun | None:
    """The run of `runs_dir` whose journal was written last (of the same modification time: whose
    last status was recorded last; one that cannot be read left out, with a warning, when another
    can); None when the folder holds no run. Raises OSError, StorageError or RunDirError
    (orbitrig.store.errors) when that run cannot be read."""
    written = [(j.stat().st_mtime_ns, j) for j in runs_dir.glob(f"*/{JOURNAL}") if (j.parent / HEADER).is_file()]
    if not written:
        return None
    newest = max(t for t, _ in written)
    tied = _readable([j for t, j in written if t == newest])
    journal, latest = max(tied, key=lambda read: (read[0].status_at, read[1].parent.name))
    header = read_header(RunLayout(latest.parent))
    return LastRun(
        run_id=header_identity(header),
        outcome=journal.status,
        message=journal.status_message,
        folder=latest.parent.resolve(),
        ended_at=journal.status_at if journal.status.final and journal.status_at else None,
    )


def _readable(journals: list[Path]) -> list[tuple[Journal, Path]]:
    """Each of ``journals`` (written at the same time) read; one that cannot be read left out with a
    warning naming it (and its line), unless none can: then the first one's error is raised."""
    read, failed = [], []
    for j in sorted(journals):
        try:
            read.append((read_journal(j), j))
        except (StorageError, RunDirError) as err:
            failed.append(err)
    for problem in failed if read else ():
        log.warning(
            "last run: %s: left out (the runs whose journals were written at the same time are compared)", problem
        )
    if not read:
        raise failed[0]
    return read


async def read_last_run_within(runs_dir: Path, within: float = READ_S) -> LastRun | None:
    """:func:`read_last_run` in a daemon thread of its own, waited for at most `within` s
    (TimeoutError): a runs folder that does not answer holds neither the service's start nor its exit."""
    done = on_daemon_thread(lambda: read_last_run(runs_dir), "orbitrig-last-run")
    async with asyncio.timeout(within):  # a cancel (the service's exit) raised even as the read returns
        return await asyncio.wrap_future(done)
