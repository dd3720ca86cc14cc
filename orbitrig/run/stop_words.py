"""The stop words to a rig's drives over a Modbus link of their own: what a command sends when it
could not open the drives (a failure, or a signal while opening them, when the drives' entry has
let go of its link at once, drives/entry.py), and what a run cancelled while it opened them sends
(orbitrig.run.closing), so that drives found turning, or not read yet, do not run on. The emergency
stop (OFF3) if asked, at once, nothing read first; else the ramp stop (OFF1), after one read of
each drive's status word (drives.read_first.read_first): a drive turning in its emergency ramp (another
link's or process' OFF3) makes it the emergency stop, a drive not read leaves it the ramp stop. A
further request meanwhile (`escalate` set, or a cancellation of the caller) makes it the emergency
stop (the words still to write are OFF3, a drive that took OFF1 gets OFF3 next, drives/stop.py),
never cuts the words short. Each drive is tried even if the other is silent."""

from __future__ import annotations

import asyncio
from dataclasses import dataclass, field

from drives.errors import DriveError
from drives.read_first import ReadFirst, read_first
from drives.stop import StopSender
from drives.stop_said import stop_kind, took_it
from drives.waits import done_or_set
from orbitrig.config import Drives
from orbitrig.run.drive_setup import bare_drives, modbus_link


@dataclass(frozen=True)
class StopWordsSent:
    """What `send_stop_words` put on the line: the drives that took the last stop word (`took`,
    'spin (id 1)'), whether that was the emergency stop (OFF3), whether a further request made it
    so after the ramp stop (OFF1) had begun (`escalated`), the errors of the drives that did
    not take it, and what the status reads before a ramp stop found (`read`; None: none made)."""

    took: list[str]
    emergency: bool
    escalated: bool
    errors: list[DriveError] = field(default_factory=list)
    read: ReadFirst | None = None

    @property
    def by_read(self) -> bool:
        """Whether the emergency stop went out because a drive was read in its emergency ramp."""
        return self.read is not None and self.read.emergency and not self.escalated

    def said(self, interrupt) -> str:
        """'ramp stop (OFF1) sent', 'SIGINT during the ramp stop: emergency stop (OFF3) sent', or
        'SIGINT: emergency stop (OFF3) sent' (asked for before the words went out); what the reads
        first found is said with the stop ('emergency stop (OFF3, as spin (id 1) read turning in
        its emergency ramp) sent', 'ramp stop (OFF1, orbit (id 2) not read) sent', drives.stop_said.stop_kind);
        `interrupt`: the command's signal record (its `received` signals)."""
        if not self.emergency or self.by_read:
            return f"{stop_kind(self.emergency, self.read)} sent"
        last = interrupt.received[-1].name if interrupt.received else ""
        why = f"{last} during the ramp stop: " if self.escalated else (f"{last}: " if last else "")
        return why + "emergency stop (OFF3) sent"


async def send_stop_words(
    url: str, d: Drives, *, emergency: bool = False, escalate: asyncio.Event | None = None
) -> StopWordsSent:
    """The stop words to both drives of [drives] `d` at `url`, over a link of their own (closed
    after): OFF3 if `emergency` or `escalate` is set already, else OFF1 (OFF3 if a drive reads in
    its emergency ramp first: `read_first`), made OFF3 (`escalated`) once `escalate` is set or the
    caller is cancelled while the drives are read or the words go out. A cancellation is not
    raised: the caller is on its way out already and says what went out."""
    link = modbus_link(url, d)
    drives = list(bare_drives(link, d))
    try:
        emergency = emergency or (escalate is not None and escalate.is_set())
        read = None if emergency else await _read_first(drives)
        # a further request while the drives were read: the emergency stop, as during the words
        early = not emergency and (read is None or (escalate is not None and escalate.is_set()))
        emergency = emergency or early or (read is not None and read.emergency)
        errors, escalated = await sent_escalating(StopSender(drives), emergency, escalate)
    finally:
        await link.close()
    return StopWordsSent(took_it(drives, errors), emergency or escalated, escalated or early, errors, read)


async def _read_first(drives: list) -> ReadFirst | None:
    """`read_first` of `drives`; None if the caller was cancelled meanwhile (the emergency stop then)."""
    try:
        return await read_first(drives)
    except asyncio.CancelledError:
        return None


async def sent_escalating(
    sender: StopSender, emergency: bool, escalate: asyncio.Event | None
) -> tuple[list[DriveError], bool]:
    """The stop (`emergency`: OFF3) through `sender`, made OFF3 once `escalate` is set or the caller
    is cancelled while it goes out (the words still to write are OFF3, a drive that took OFF1 gets
    OFF3 next): (its delivery errors, whether it was made so). Also the service's idle ramp stop's
    (orbitrig.service.idle_stop: an abort meanwhile)."""
    stop, escalated = sender.send(emergency=emergency), False
    while not stop.done():
        cancelled, fired = False, None
        asked = () if escalate is None or emergency or escalated else (escalate,)  # once OFF3: nothing to ask for
        try:
            fired = await done_or_set(stop, *asked)
        except asyncio.CancelledError:
            cancelled = True
        asked_now = escalate is not None and bool(asked) and (fired is escalate or escalate.is_set())  # (same turn too)
        if not (emergency or escalated) and (cancelled or asked_now):
            stop, escalated = sender.send(emergency=True), True  # takes the ramp stop's words over
    return stop.result(), escalated
