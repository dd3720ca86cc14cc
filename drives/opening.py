"""What opening the drives does to each one, and what leaving them running relies on.

- `params_to_write`: the ramp and watchdog parameters given that a drive does not hold yet.
- `clear_stale_comm_loss`: fault 7510 left by a previous client, reset at standstill.
- `watchdog_words`: whether the drives' comm-loss watchdog stops them once nobody polls.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence

from drives import registers as R
from drives.drive import Drive, DriveParameters, DriveStatus
from drives.errors import DriveFaultError

log = logging.getLogger(__name__)


def params_to_write(held: DriveParameters | None, wanted: Mapping[str, float | None]) -> dict[str, float]:
    """The `wanted` parameters (s; None: not given) that differ from what a drive holds (`held`,
    None: unread); one register unit apart at most counts as equal: a drive that already holds
    them, running or not, is left alone."""
    out = {}
    for name, value in wanted.items():
        if value is None:
            continue
        if held is None or abs(getattr(held, name) - value) >= R.TIME_UNIT / 2:
            out[name] = value
    return out


async def clear_stale_comm_loss(drive: Drive) -> DriveStatus:
    """`drive`'s status; at standstill showing fault 7510 (the previous client went away) it is
    reset first: talking to it removed the cause. Other faults stay for `reset_faults`; a reset
    the drive refuses leaves it tripped."""
    st = await drive.read_status()
    if st.tripped and st.fault_code == R.FAULT_COMM_LOSS and st.stopped:
        log.warning(
            "%s drive (id %d): resetting fault 7510 left by a previous client (at standstill)",
            drive.name,
            drive.device_id,
        )
        try:
            st = await drive.reset_fault()
        except DriveFaultError as err:
            log.warning("%s", err)
            st = await drive.read_status()
    return st


def watchdog_words(drives: Sequence[Drive]) -> str:
    """What stops drives nobody polls: their comm-loss watchdog as last read (COMM_LOSS_TIMEOUT)."""
    times = [d.params.comm_loss_timeout if d.params else 0.0 for d in drives]
    if all(t > 0 for t in times):
        return f"without a polling client their comm-loss watchdog ramps them down after {max(times):g} s"
    return "their comm-loss watchdog is not known to be armed (COMM_LOSS_TIMEOUT 0 or unread): nothing stops them"
