"""The stop words to a rig's drives over a Modbus link of their own, no reads first: what a command
sends when it could not open the drives (a failure, or a signal while opening them, when the
drives' entry has let go of its link at once, drives/entry.py), and what a run cancelled while it
opened them sends (orbitrig.run.closing), so that drives found turning, or not read yet, do not run on. The ramp stop (OFF1), or the emergency stop (OFF3) if asked; a
further request meanwhile (`escalate` set, or a cancellation of the caller) makes it the emergency
stop (the words still to write are OFF3, a drive that took OFF1 gets OFF3 next, drives/stop.py),
never cuts the words short. Each drive is tried even if the other is silent."""

from __future__ import annotations

import asyncio
from dataclasses import dataclass, field

from drives.errors import DriveError
from drives.stop import StopSender, took_it
from orbitrig.config import Drives
from orbitrig.run.drive_setup import bare_drives, modbus_link


@dataclass(frozen=True)
class StopWordsSent:
    """What `send_stop_words` put on the line: the drives that took the last stop word (`took`,
    'spin (id 1)'), whether that was the emergency stop (OFF3), whether a further request made it
    so after the ramp stop (OFF1) had begun (`escalated`), and the errors of the drives that did
    not take it."""

    took: list[str]
    emergency: bool
    escalated: bool
    errors: list[DriveError] = field(default_factory=list)

    def said(self, interrupt) -> str:
        """'ramp stop (OFF1) sent', 'SIGINT during the ramp stop: emergency stop (OFF3) sent', or
        'SIGINT: emergency stop (OFF3) sent' (asked for before the words went out); `interrupt`:
        the command's signal record (its `received` signals)."""
        if not self.emergency:
            return "ramp stop (OFF1) sent"
        last = interrupt.received[-1].name if interrupt.received else ""
        why = f"{last} during the ramp stop: " if self.escalated else (f"{last}: " if last else "")
        return why + "emergency stop (OFF3) sent"


async def send_stop_words(
    url: str, d: Drives, *, emergency: bool = False, escalate: asyncio.Event | None = None
) -> StopWordsSent:
    """The stop words to both drives of [drives] `d` at `url`, over a link of their own (closed
    after): OFF3 if `emergency` or `escalate` is set already, else OFF1, made OFF3 once `escalate`
    is set or the caller is cancelled while they go out. A cancellation is not raised: the caller
    is on its way out already and says what went out."""
    link = modbus_link(url, d)
    drives = list(bare_drives(link, d))
    sender = StopSender(drives)
    emergency = emergency or (escalate is not None and escalate.is_set())
    stop, escalated = sender.send(emergency=emergency), False
    asked = asyncio.ensure_future(escalate.wait()) if escalate is not None and not emergency else None
    try:
        while not stop.done():
            cancelled = False
            try:
                await asyncio.wait([stop] if asked is None else [stop, asked], return_when=asyncio.FIRST_COMPLETED)
            except asyncio.CancelledError:
                cancelled = True
            if not (emergency or escalated) and (cancelled or (asked is not None and asked.done())):
                stop, escalated = sender.send(emergency=True), True  # takes the ramp stop's words over
            if escalated and asked is not None:
                asked.cancel()
                asked = None  # nothing more to ask for
        errors = stop.result()
    finally:
        if asked is not None:
            asked.cancel()
        await link.close()
    return StopWordsSent(took_it(drives, errors), emergency or escalated, escalated, errors)
