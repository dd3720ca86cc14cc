"""run.log and the commands' journal lines, written by a thread of their own.

A line is stamped when it is said and written later, in the order said, by one
thread (`RECORDS`), so the event loop that polls the drives and passes an abort on
never waits for the disk: a slow or stalled disk delays the file, not the rig.
Between two completed points both logs are bounded (orbitrig.store.quota); the
quotas are touched in that thread only. `flush` waits until everything said so far
is written (the run's end, before run.h5 copies the journal).
"""

from __future__ import annotations

import logging
import os
import threading
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import TypeVar

from orbitrig.store import journal
from orbitrig.store.durable import APPEND_FLAGS
from orbitrig.store.errors import StorageError
from orbitrig.store.journal_file import JournalFile
from orbitrig.store.quota import COMMANDS_HEAD, COMMANDS_TAIL, RUN_LOG_HEAD, RUN_LOG_TAIL, LineQuota
from rigunits import now_iso, utc_iso

log = logging.getLogger(__name__)
T = TypeVar("T")
_here = threading.local()
RECORDS = ThreadPoolExecutor(
    max_workers=1, thread_name_prefix="orbitrig-records", initializer=lambda: setattr(_here, "records", True)
)


class RunLog:
    """The run directory's run.log (`path`) and the commands' lines of its journal
    (`journal`, shared with the store's lines); every method returns at once except
    `close_interval` and `flush`."""

    def __init__(self, path: Path, journal: JournalFile):
        self.path = path
        self._journal = journal
        self._failed = False
        self._lines = LineQuota(RUN_LOG_HEAD, RUN_LOG_TAIL)
        self._commands = LineQuota(COMMANDS_HEAD, COMMANDS_TAIL)

    def line(self, message: str) -> None:
        """A run.log line, stamped now (best effort: a full disk must not stop the run). Between two
        completed points the first RUN_LOG_HEAD lines are written at once, the newest RUN_LOG_TAIL
        held until the interval closes, the rest counted."""
        _later(self._write_line, f"{utc_iso()} {message}\n")

    def command(self, command: str, by: str, detail: str = "") -> None:
        """A command that changed the run, who sent it and when: a journal line (run.h5's
        /logs/commands) and a run.log line. Best effort: a storage failure is logged."""
        text = f"{utc_iso()} command {command} by {by}" + (f" ({detail})" if detail else "") + "\n"
        entry = journal.line("command", command=command, by=by, at=now_iso(), detail=detail)
        _later(self._write_command, text, entry)

    def close_interval(self, until: str) -> list[str]:
        """Close the logs' interval at `until` once every line said before is written: run.log gets
        what was left out of it (a count, then the newest lines held); returned: the journal's
        command lines to append (likewise)."""
        return _in_records(self._close, until)

    def flush(self) -> None:
        """Wait until every line said so far is written."""
        _in_records(lambda: None)

    # ------------------------------------------------------- in RECORDS
    def _write_line(self, line: str) -> None:
        if self._lines.offer(line):
            self._append(line)

    def _write_command(self, text: str, entry: str) -> None:
        self._write_line(text)
        if not self._commands.offer(entry):
            return
        try:
            self._journal.append([entry])
        except StorageError as err:
            log.error("cannot journal %s: %s", entry, err)

    def _append(self, text: str) -> None:
        try:
            with open(os.open(self.path, APPEND_FLAGS, 0o644), "a", encoding="utf-8") as fh:
                fh.write(text)
        except OSError as err:
            if not self._failed:
                log.error("cannot write %s: %s (further run.log lines are lost)", self.path, err)
            self._failed = True

    def _close(self, until: str) -> list[str]:
        text, commands = self._lines.close(), self._commands.close()
        if text.tail:
            note = f"{text.count + len(text.tail)} lines since the last completed point were not written at once"
            self._append(
                f"{utc_iso()} run.log: {note} (until {until}): {text.count} left out, the newest "
                f"{len(text.tail)} follow\n" + "".join(text.tail)
            )
        if not commands.tail:
            return []
        note = f"{commands.count} commands left out (the journal keeps {COMMANDS_HEAD} per point and the newest)"
        left = [journal.line("command", command="(left out)", by="", at=now_iso(), detail=note)]
        return (left if commands.count else []) + commands.tail


def _later(fn: Callable[..., None], *args: object) -> None:
    """`fn(*args)` in RECORDS after everything submitted before it; its failure is logged."""
    try:
        RECORDS.submit(fn, *args).add_done_callback(_report)
    except RuntimeError:  # the interpreter is shutting down: no thread takes work any more
        fn(*args)


def _in_records(fn: Callable[..., T], *args: object) -> T:
    """`fn(*args)` in RECORDS after everything submitted before it, waited for."""
    if getattr(_here, "records", False):
        return fn(*args)
    try:
        done = RECORDS.submit(fn, *args)
    except RuntimeError:  # the interpreter is shutting down
        return fn(*args)
    return done.result()


def _report(done: Future[None]) -> None:
    if not done.cancelled() and (err := done.exception()) is not None:
        log.error("run.log: %s: %s", type(err).__name__, err)
