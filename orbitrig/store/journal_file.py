"""journal.jsonl as the process writing the run appends to it: the store's lines and the commands
the run log's thread writes (orbitrig.store.run_log) go through one `JournalFile`, under one lock.

A journal this process has written to (or found when it opened the run) and that is gone at the
next append was deleted while the run went on: it is not created again silently. The new file
starts with a ``continued`` line (at, detail: what was lost), the run's last status written again
and an event saying so (run.h5's /logs/events), and `told` is told the warning (the run's writer:
run.log, and whoever `RunStore.warned` names: the run engine's subscribers, orbitrig.run.store_notes;
else the terminal). Every reader of the run warns of it (orbitrig.store.journal: `Journal.continued`).
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from pathlib import Path

from orbitrig.store import journal
from orbitrig.store.durable import append_lines
from orbitrig.store.status import RunStatus
from rigunits import now_iso


def deleted(path: Path, at: str, resumed: bool = False) -> str:
    """The warning that the journal `path` was deleted while the run went on (found gone `at`), or
    (`resumed`) was missing when the run was resumed: a new journal continues it."""
    when = "was missing when the run was resumed" if resumed else "was deleted while the run was being written"
    return (
        f"{path} {when} (found missing at {at}): the status, commands, events and CAN and drive logs it "
        "held until then are lost; a new journal.jsonl continues it from there"
    )


class JournalFile:
    """The run's journal `path` for its writer: `append` (any thread), `expect` (it exists: one
    missing at the next append was deleted), `status_line` and `event` the lines of the run's status
    and of an event of the store's own (`clock`: seconds since the run started), `told(warning)`
    the warning said when the journal is found deleted."""

    def __init__(self, path: Path, clock: Callable[[], float], told: Callable[[str], None]):
        self.path = path
        self.clock, self.told = clock, told
        self._lock = threading.Lock()
        self._expected = False  # True once written (or found) by this process
        self._status: tuple[RunStatus, str] = (RunStatus.RUNNING, "")  # the last one written
        self._said: dict[str, tuple[RunStatus, str]] = {}  # status lines made, not written yet

    def expect(self) -> None:
        """The journal is there now (an existing run opened): gone later means deleted."""
        with self._lock:
            self._expected = os.path.lexists(self.path)

    def status_line(self, status: RunStatus, message: str) -> str:
        """The journal line of the run's status (held as the run's once appended)."""
        text = journal.status_line(status, message)
        with self._lock:
            self._said[text] = (status, message)
        return text

    def event(self, message: str) -> str:
        """The journal line of an event the store itself records (run.h5's /logs/events), in the
        state of the run's last status written."""
        return journal.line("event", t=self.clock(), state=str(self._status[0]), message=message)

    def append(self, lines: list[str]) -> None:
        """Append `lines` in one durable write (orbitrig.store.durable.append_lines); a journal
        deleted since this process wrote it is started again as a continuation (a `continued`
        line, the run's status as it stands, the warning as an event), said."""
        if not lines:
            return
        warning = ""
        with self._lock:
            lead: list[str] = []
            if self._expected and not os.path.lexists(self.path):
                found = now_iso()
                warning = deleted(self.path, found)
                status, message = self._status
                lead = [
                    journal.line("continued", at=found, detail=warning),
                    journal.status_line(status, message),
                    self.event(f"warning: {warning}"),
                ]
            append_lines(self.path, lead + lines)
            self._expected = True
            for text in lines:
                if text in self._said:
                    self._status = self._said.pop(text)
        if warning:
            self.told(warning)
