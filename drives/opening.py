"""What opening the drives does to each one, and what leaving them running relies on.

- `params_to_write`: the ramp and watchdog parameters given that a drive does not hold yet.
- `clear_stale_comm_loss`: fault 7510 the watchdog tripped after the last client let go, reset at standstill.
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
            "%s drive (id %d): at standstill with fault 7510, its comm-loss watchdog's since the last client "
            "(an earlier run or command, this program's too) let it go: reset",
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
    """What stops drives once nobody polls them, as their parameters last read: their comm-loss
    watchdog (COMM_LOSS_TIMEOUT) in seconds where every one is armed; else the drives whose
    watchdog reads 0, or that it is not known (parameters unread), and the rig's emergency stop."""
    times = [(d, d.params.comm_loss_timeout if d.params is not None else None) for d in drives]
    armed = [t for _, t in times if t]
    if len(armed) == len(times):
        return f"their comm-loss watchdog (COMM_LOSS_TIMEOUT) ramps them down {max(armed):g} s after the last request"
    off = [f"{d.name} (id {d.device_id})" for d, t in times if t == 0]
    if off:
        where = ", ".join(off)
        return f"COMM_LOSS_TIMEOUT reads 0 (no watchdog) on {where}: nothing stops it; use the rig's emergency stop"
    return "their comm-loss watchdog is not known (parameters not read); use the rig's emergency stop"
