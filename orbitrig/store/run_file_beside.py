"""What the run.h5 consolidated beside a run in pieces tells a reader of the pieces
(docs/storage.md, "A directory that holds the pieces"): where the run is still whole when its
run.json cannot be read, and that a journal.jsonl without its final status lost it.

The writer appends the run's final status to the journal first and only then renames run.h5
into place; a resume removes the run.h5 before it says `running` again. So a run.h5 with a final
status beside a journal without one means the journal was cut short or edited, as long as the
journal is read after run.h5 is found (a run that has just ended is not mistaken for one) and it
is not a resume's new journal before its first status."""

from __future__ import annotations

from pathlib import Path

from orbitrig.store.errors import RunDirError, StorageError
from orbitrig.store.h5_values import open_h5, text
from orbitrig.store.journal import Journal, read_journal
from orbitrig.store.layout import READABLE_FORMATS, RunLayout
from orbitrig.store.status import RunStatus


def whole_file_beside(layout: RunLayout, unreadable: str | Path) -> str:
    """Where a run whose header `unreadable` cannot be read is still whole: its run.h5, when
    there is one of a format this version reads ("" otherwise, or for another file)."""
    if Path(unreadable) != layout.header or not layout.run_file.is_file():
        return ""
    try:
        with open_h5(layout.run_file) as h5:
            if text(h5.attrs.get("format")) not in READABLE_FORMATS:
                return ""
    except (RunDirError, OSError):
        return ""
    return (
        f"; {layout.run_file}, consolidated when the run ended, holds the run: read that file "
        f"(orbitrig.open_run('{layout.run_file}'), or a folder holding only it for orbitrig's commands)"
    )


def journal_cut_short(layout: RunLayout, journal: Journal) -> str:
    """The warning that the journal of `layout`, read as `journal`, lost its final status: it has
    none, and the run.h5 beside it records one ("" otherwise). The journal is read again once
    run.h5 is found: it may have gained its final status since `journal` was read (the run ended
    in between), and then nothing is wrong. A journal that holds only the `continued` line a resume
    writes when it finds the journal missing (no status yet) is a resume under way, its run.h5 not
    yet removed: the continued warning says the status was lost."""
    if journal.status.final or not layout.journal.exists():
        return ""
    ended = _file_status(layout.run_file)
    if not ended:
        return ""
    try:
        again = read_journal(layout.journal)
    except (StorageError, RunDirError):
        return ""  # gone or damaged since: its own reader says so next time
    if again.status.final or (again.continued and not again.status_at):
        return ""  # ended meanwhile; or a resume of a run whose journal was lost, before it says running
    return (
        f"warning: {layout.journal} says the run is {again.status}, but {layout.run_file}, written only "
        f"after the journal's final status, says {ended}: the journal was cut short or edited "
        f"({again.torn} unreadable line(s)); run.h5 holds the run's status and logs as it ended"
    )


def _file_status(path: Path) -> RunStatus | None:
    """The final status the run file at `path` records (None when none is there, it cannot be
    read, or its status is not final)."""
    if not path.is_file():
        return None
    try:
        with open_h5(path) as h5:
            status = RunStatus.read(text(h5.attrs.get("status")))
    except (RunDirError, OSError):
        return None
    return status if status.final else None
