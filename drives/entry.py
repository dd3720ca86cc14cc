"""An entry of the rig that failed once the link was connected (`RigDrives.__aenter__`).

Drives found turning there (left running by a released rig, a crashed process, their keypad)
would run on unwatched once the link closes. So, before it closes: each drive not read yet is read
once (not after a cancellation or Ctrl-C: it counts as turning), and if any drive reads turning (operation
enabled, or a nonzero actual speed) or could not be read, both get the ramp stop (OFF1) by the
rig's own stop (`RigDrives._safe_stop`: delivered even if the task is cancelled meanwhile, or
during those reads: then raised once it is out). What
was found and what the stop reached is noted on the entry's own exception, which goes on, and
logged as a warning.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Awaitable, Callable, Sequence

from drives.drive import Drive, DriveStatus
from drives.errors import DriveError
from drives.limits import fmt_speed
from drives.stop import took_it

log = logging.getLogger(__name__)


class Entry:
    """What an entry has read of its drives: the link connected, each drive's status."""

    def __init__(self, drives: Sequence[Drive]):
        self.drives = drives
        self.connected = False
        self.statuses: dict[int, DriveStatus] = {}  # device id -> its status read on entry

    async def failed(self, err: BaseException, stop: Callable[[], Awaitable[list[DriveError]]]) -> None:
        """After `err` ended the entry, link connected: both drives stopped if any may be turning,
        said on `err` (a note). A cancellation during the reads or the stop is raised once it has gone out."""
        found, cancelled = [], not isinstance(err, Exception)  # a cancellation: no drive read again
        for d in self.drives:
            try:
                found.append(await self._found(d, reread=not cancelled))
            except asyncio.CancelledError:  # Ctrl-C during the read: the stop all the same
                cancelled = True
                found.append("not read (may be turning): cancelled")
        if all(words is None for words in found):
            if cancelled and isinstance(err, Exception):
                raise asyncio.CancelledError
            return
        what = "; ".join(f"{d.name} (id {d.device_id}) {words}" for d, words in zip(self.drives, found) if words)
        sent = f"the entry failed with {what}: the ramp stop (OFF1) sent to " + ", ".join(took_it(self.drives, []))
        try:
            errors = await stop()
        except asyncio.CancelledError:
            _said(err, f"{sent}, then cancelled")
            raise
        reached = ", ".join(took_it(self.drives, errors)) or "no drive"
        missed = "; ".join(f"not confirmed: {e}" for e in errors)
        said = f"taken by {reached}" + (f"; {missed}" if missed else "")
        _said(err, f"{sent}: {said}")
        if cancelled and isinstance(err, Exception):  # cancelled during the reads: raised once the stop is out
            raise asyncio.CancelledError

    async def _found(self, d: Drive, *, reread: bool) -> str | None:
        """How drive `d` was found: 'running at ...', 'not read (may be turning): ...', or None
        (at standstill, not running)."""
        st = self.statuses.get(d.device_id)
        if st is None and reread:
            try:
                st = await d.read_status(retries=0)
            except Exception as why:  # noqa: BLE001 - whatever the read raised, the drive is not known stopped
                return f"not read (may be turning): {why}"
        if st is None:
            return "not read (may be turning)"
        if st.running or not st.stopped:
            kind = "running" if st.running else f"turning ({st.state})"
            return f"{kind} at {fmt_speed(st.actual)}"
        return None


def _said(err: BaseException, words: str) -> None:
    """`words` noted on `err` (it goes on) and logged as a warning (a command's standard error)."""
    err.add_note(words)
    log.warning("%s (%s)", words, type(err).__name__)
