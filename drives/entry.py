"""An entry of the rig that failed once the link was connected (`RigDrives.__aenter__`).

Drives found turning there (left running by a released rig, a crashed process, their keypad)
would run on unwatched once the link closes. So, before it closes, after an exception (a timeout,
a parameter write refused): each drive not read yet is read once, and if any drive reads turning
(operation enabled, or a nonzero actual speed) or could not be read, both get the ramp stop (OFF1),
the emergency stop (OFF3) if a drive reads turning in its emergency stop (a ramp stop word would
slow that ramp tenfold), by the rig's own stop (`RigDrives._safe_stop`: delivered even if the task
is cancelled meanwhile).
What was found and what the stop reached is noted on the entry's own exception, which goes on, and
logged as a warning.

A cancellation of the entry (an abort, Ctrl-C), also during those reads, lets go of the link at
once: whoever cancelled it stops the drives over a link of its own (an abort's emergency stop,
orbitrig.service.idle_stop; the stop words of `orbitrig drives stop` and `drives run`), which a ramp stop from here
would hold up (an RTU port is one link at a time) or follow (an OFF1 after their OFF3).
"""

from __future__ import annotations

import logging
from collections.abc import Awaitable, Callable, Sequence

from drives.drive import Drive, DriveStatus
from drives.errors import DriveError
from drives.limits import fmt_speed
from drives.stop_said import stop_kind, took_it

log = logging.getLogger(__name__)


class Entry:
    """What an entry has read of its drives: the link connected, each drive's status."""

    def __init__(self, drives: Sequence[Drive]):
        self.drives = drives
        self.connected = False
        self.statuses: dict[int, DriveStatus] = {}  # device id -> its status read on entry
        self.failed_on: BaseException | None = None  # what ended a failed entry once connected
        self.stop_sent = False  # whether a failed entry sent both drives its stop (`failed`)

    async def failed(self, err: BaseException, stop: Callable[[bool], Awaitable[list[DriveError]]]) -> None:
        """After `err` ended the entry, link connected: both drives stopped (`stop(emergency)`) if any
        may be turning, said on `err` (a note). Nothing after a cancellation (`err`, or one during the reads)."""
        self.failed_on = err
        if not isinstance(err, Exception):
            return
        found = [await self._found(d) for d in self.drives]
        if all(words is None for words in found):
            return
        what = "; ".join(f"{d.name} (id {d.device_id}) {words}" for d, words in zip(self.drives, found) if words)
        emergency = any(st.emergency_ramp for st in self.statuses.values())
        sent = f"the entry failed with {what}: the {stop_kind(emergency)} sent to " + ", ".join(
            took_it(self.drives, [])
        )
        self.stop_sent = True
        errors = await stop(emergency)
        reached = ", ".join(took_it(self.drives, errors)) or "no drive"
        missed = "; ".join(f"not confirmed: {e}" for e in errors)
        _said(err, f"{sent}: taken by {reached}" + (f"; {missed}" if missed else ""))

    async def _found(self, d: Drive) -> str | None:
        """How drive `d` was found (read again if not read yet): 'running at ...', 'not read (may
        be turning): ...', or None (at standstill, not running)."""
        st = self.statuses.get(d.device_id)
        if st is None:
            try:
                st = self.statuses[d.device_id] = await d.read_status(retries=0)
            except Exception as why:  # noqa: BLE001 - whatever the read raised, the drive is not known stopped
                return f"not read (may be turning): {why}"
        if st.running or not st.stopped:
            kind = "running" if st.running else f"turning ({st.state})"
            return f"{kind} at {fmt_speed(st.actual)}"
        return None


def _said(err: BaseException, words: str) -> None:
    """`words` noted on `err` (it goes on) and logged as a warning (a command's standard error)."""
    err.add_note(words)
    log.warning("%s (%s)", words, type(err).__name__)
