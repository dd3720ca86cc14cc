"""The status read before a ramp stop over a bare link (no RigDrives reading the drives:
`send_stop_words`, the service's idle stop): each drive's status word first (`read_first`: one
exchange each, no retries, within the link's request timeout). A drive read turning in its
emergency ramp (SW OFF_3_STA 0, whoever sent that OFF3, another link or process among them) makes
it the emergency stop (OFF3); a drive that cannot be read leaves it the ramp stop, said as not read
(drives/stop_said.py `stop_kind`). An emergency stop reads nothing first.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from drives import registers as R
from drives.errors import DriveConnectError, DriveError

if TYPE_CHECKING:
    from drives.drive import Drive

log = logging.getLogger("drives.stop")  # its warnings are the stop's (the command line names the logger)


@dataclass(frozen=True)
class ReadFirst:
    """What the status reads before a ramp stop over a bare link found (`read_first`): the drives
    read turning in their emergency ramp ('spin (id 1)', ...), those that could not be read."""

    in_emergency: tuple[str, ...] = ()
    unread: tuple[str, ...] = ()

    @property
    def emergency(self) -> bool:
        """Whether the stop must be the emergency stop (OFF3): a drive is in its emergency ramp."""
        return bool(self.in_emergency)

    def said(self) -> str:
        """'as spin (id 1) read turning in its emergency ramp; orbit (id 2) not read', or ''."""
        parts = []
        if self.in_emergency:
            their = "its" if len(self.in_emergency) == 1 else "their"
            parts.append(f"as {', '.join(self.in_emergency)} read turning in {their} emergency ramp")
        if self.unread:
            parts.append(f"{', '.join(self.unread)} not read")
        return "; ".join(parts)


async def read_first(drives: Sequence[Drive]) -> ReadFirst:
    """Each drive's status word read before a ramp stop over a bare link: one exchange each, no
    retries, within the link's request timeout (a link that cannot be connected is not tried again
    for the next drive). A drive turning in its emergency ramp (SW OFF_3_STA 0, actual speed not
    zero) makes the stop the emergency stop; a failed read only says the drive was not read."""
    in_emergency: list[str] = []
    unread: list[str] = []
    no_link = False
    for d in drives:
        name = f"{d.name} (id {d.device_id})"
        if no_link:
            unread.append(name)
            continue
        try:
            w = await d.link.read(d.device_id, *R.PROCESS_DATA, retries=0)
        except Exception as err:  # noqa: BLE001 - whatever the read raised, the stop goes out
            why = err if isinstance(err, DriveError) else f"{d.name} drive (id {d.device_id}): {err!r}"
            log.warning("status not read before the ramp stop: %s", why)
            unread.append(name)
            no_link = isinstance(err, DriveConnectError)
            continue
        if R.in_emergency_ramp(w[R.SW], R.from_word(w[R.ACT])):
            log.warning(
                "%s drive (id %d) turning in its emergency ramp: the emergency stop instead", d.name, d.device_id
            )
            in_emergency.append(name)
    return ReadFirst(tuple(in_emergency), tuple(unread))
