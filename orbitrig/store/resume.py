"""A run's resume (mixin of the run's writer, orbitrig.store.writer.RunStore): every point verified
in full, each incomplete or damaged one set aside under DIR/aside (never deleted), leftover
temporary files and a stale run.h5 removed, a journal.jsonl gone said; what it did is said in
run.log and `set_aside`."""

from __future__ import annotations

import contextlib
import logging
import os
from collections.abc import Callable
from pathlib import Path

from orbitrig.store import csvfile, journal
from orbitrig.store.consolidate import RunImage
from orbitrig.store.durable import TMP_SUFFIX, fsync_dir
from orbitrig.store.errors import storage_error
from orbitrig.store.index import NEVER_COMPLETED, CompletePoints
from orbitrig.store.journal_file import JournalFile, deleted
from orbitrig.store.layout import RUN_FILE, RunLayout, point_name
from orbitrig.store.status import RunStatus
from rigunits import now_iso

log = logging.getLogger("orbitrig.store.writer")
#: said when a resume removes the run.h5 written before it, and by the end of one that ends without run.h5
REMOVED_RUN_FILE = f"{RUN_FILE} written before this resume removed (stale): consolidated again when the run ends"
REMOVED_BEFORE = f"the {RUN_FILE} written before this resume was removed as it started (stale)"


class RunResume:
    """The resume part of `RunStore`."""

    layout: RunLayout
    dir: Path
    set_aside: list[str]
    removed_run_file: bool
    journal_missing: str
    _csv_points: dict[int, csvfile.PointCsv]
    _complete: CompletePoints
    _image: RunImage
    _journal_file: JournalFile
    _journal: Callable[[list[str]], None]
    log: Callable[[str], None]
    write_csv: Callable[[], None]

    def prepare_resume(self) -> list[int]:
        """Verify every point in full, set aside each incomplete or damaged one (DIR/aside/PPPP.<reason>.N),
        remove leftover temporary files and a stale run.h5; the complete point indexes. `set_aside` lists
        what was moved or removed and a missing journal.jsonl (said in run.log and on the terminal too)."""
        self.set_aside, self.removed_run_file = [], False
        self._image.close()
        self.journal_missing = journal.missing(self.layout.journal)  # before a status line below makes a new one
        if self.journal_missing:  # the new one says it continues a journal lost (every reader warns)
            self._journal(
                [journal.line("continued", at=now_iso(), detail=deleted(self.layout.journal, now_iso(), True))]
            )
        states = self._complete.verified()  # once per resume: shared with the sweep's question before it
        for st in states:
            if not st.complete:
                self._put_aside(st.index, "incomplete" if st.problem == NEVER_COMPLETED else "damaged", st.problem)
        for tmp in self.dir.glob(f"*{TMP_SUFFIX}"):
            with contextlib.suppress(OSError):
                tmp.unlink()
        with contextlib.suppress(OSError):  # a run.h5 written before: stale, consolidated again at the end
            self.layout.run_file.unlink()
            self.removed_run_file = True
        said = [f"warning: {self.journal_missing}"] if self.journal_missing else []
        said += [REMOVED_RUN_FILE] if self.removed_run_file else []
        for msg in said:
            log.warning("%s", msg)
            self.log(f"resume: {msg}")
        self.set_aside += said
        self._csv_points.clear()
        self.write_csv()  # before it says running again: a failure leaves its ended status
        self._journal([self._journal_file.status_line(RunStatus.RUNNING, "resumed")])
        return [st.index for st in states if st.complete]

    def _put_aside(self, index: int, reason: str, problem: str) -> None:
        src = self.layout.point_dir(index)
        dest = self.layout.aside_dir(index, reason)
        try:
            dest.parent.mkdir(exist_ok=True)
            os.replace(src, dest)
            fsync_dir(self.layout.points)
        except OSError as err:
            raise storage_error(src, f"move aside to {dest}", err) from err
        msg = f"point {point_name(index)} set aside as {dest.relative_to(self.dir)} ({problem}); it will be measured again"
        self.set_aside.append(msg)
        log.warning("%s", msg)
        self.log(f"resume: {msg}")
        self._journal([journal.line("point", point=index, action="set_aside", detail=msg)])
