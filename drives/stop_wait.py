"""The wait for standstill after a stop (`RigDrives.stop`), judged on the poll's statuses.

Standstill is a poll after the stop command with the link up and the drives at zero speed. When one
drive missed the stop, the one that took it is waited for; while the poll fails on the silent one
(the link down: no poll reads either), the one that took it is read by itself. While a write the
link gave up on before the stop may still reach a drive (drives/late.py: a start's word held in a
slow path), that is not enough: the drives must also be read at rest (not operation enabled, REF 0,
ACT 0) by reads sent after the last such write can have arrived; meanwhile the poll reads them every
quarter interval and gives the stop again to one read running or at a nonzero REF (drives/poll.py).
The wait is lengthened to cover that window if it is shorter.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

from drives import registers as R
from drives.errors import DriveError, DriveTimeoutError, StopTripError
from drives.late import at_rest
from drives.poll_pace import read_again_by
from drives.waits import first_set
from drives.state import RigDriveState

if TYPE_CHECKING:
    from drives.poll import DrivePoll


def _past_late(st: RigDriveState, of: frozenset[int], late_until: float | None) -> bool:
    """Whether the drives of device ids `of` were read at rest by reads asked after `late_until`
    (None: no write given up may still arrive)."""
    if late_until is None:
        return True
    read = [s for s in (st.spin, st.orbit) if s is not None and s.device_id in of]
    return all(s.asked > late_until and at_rest(s) for s in read)


async def _read_by_themselves(poll: DrivePoll, of: frozenset[int]) -> RigDriveState | None:
    """The poll's state with the drives of device ids `of` (those that took the stop) read now by
    themselves (`DrivePoll.read_now`): the poll fails while the drive that missed the stop is silent
    (the link down: no poll reads the other), though the drive that took it still answers. None
    if a read fails."""
    try:
        return await poll.read_now(of)
    except DriveError:
        return None


async def wait_stopped(
    poll: DrivePoll,
    known: frozenset[int],
    since: float,
    timeout: float,
    *,
    stop: str,
    of: frozenset[int] | None = None,
) -> None:
    """Wait up to `timeout` s past `since` (monotonic s, the stop command) for a poll after it
    with the link up (with the link down, `of`'s drives read by themselves after it) and both
    drives (`of`: those device ids) at zero speed, read at rest after any
    write given up before it could arrive (the wait lengthened to that window's end + two polls + a
    request's timeout). Then, or once the wait ends: StopTripError if a drive not in `known`
    (`known_trips` before the command) reads tripped in a poll after `since` (`stop`: which stop,
    for the message), else DriveTimeoutError if not at standstill. A poll is asked for right after
    the command (drives at standstill already), then every quarter interval until standstill, as
    `RigDrives.wait_settled` asks until the setpoint."""
    ids = of if of is not None else frozenset(d.device_id for d in poll.drives)
    late_until = poll.link.late.until(ids, at=since)
    deadline = since + timeout
    if late_until is not None:
        deadline = max(deadline, read_again_by(late_until, poll.poll_interval, poll.link.timeout))
    poll.pace.ask(since)
    while True:
        tick, st = poll.tick, poll.state
        poll.alive()
        by_themselves = None
        if not st.link_ok and of is not None:  # (once more past the deadline: the stop sent again may fill the wait)
            by_themselves = await _read_by_themselves(poll, of)
        st = by_themselves or st
        read = st.link_ok or by_themselves is not None
        standstill = read and st.time > since and st.stopped_of(of) and _past_late(st, ids, late_until)
        if standstill or time.monotonic() >= deadline:
            break
        if st.link_ok and st.time > since:  # not there yet: read again soon
            poll.pace.ask(st.time + poll.poll_interval / 4)
        await first_set(tick, timeout=deadline - time.monotonic())
    waited = timeout if late_until is None else deadline - since
    late = f"not at zero speed within {waited:g} s: " + st.describe(since, "the stop")
    tripped = [s for s in (st.spin, st.orbit) if s and s.tripped and s.time > since and s.device_id not in known]
    if tripped:
        raise StopTripError(tripped, stop=stop, standstill=standstill, end=late)
    if not standstill:
        raise DriveTimeoutError("drives " + late, register=R.ACT)
