"""Every emergency stop word (OFF3) written to a drive, whoever sent it (a run's RigDrives, a bare
`send_stop` over a link of its own), remembered per link URL until speeds are commanded there
(`speeds_commanded`): `emergency_within` says whether one went out less than so many seconds ago, for
a stop asked then to be the emergency stop too (a ramp stop word would turn the drives' emergency
ramp back into their ten times slower ramp stop). drives/stop.py notes each one as it goes out.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from drives.drive import Drive

#: link URL -> monotonic s of the last emergency stop word (OFF3) written to a drive on it, no speed
#: commanded there since (`emergency_within`)
_EMERGENCY_SENT: dict[str, float] = {}


def emergency_sent(url: str) -> None:
    """An emergency stop word goes out to a drive on the link at `url` now (noted before it goes
    out: a write that fails may still have reached the drive)."""
    _EMERGENCY_SENT[url] = time.monotonic()


def emergency_within(url: str, seconds: float) -> bool:
    """Whether an emergency stop word went out to a drive on the link at `url` less than `seconds`
    (monotonic) ago, no speed commanded there since: the drives may still be in their emergency ramp."""
    at = _EMERGENCY_SENT.get(url)
    return at is not None and time.monotonic() - at < seconds


def speeds_commanded(drives: Sequence[Drive]) -> None:
    """Speeds were commanded to `drives`: an emergency stop sent to them before is over."""
    for d in drives:
        _EMERGENCY_SENT.pop(d.link.url, None)
