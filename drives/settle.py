"""The wait for the setpoint (`RigDrives.wait_settled`): both drives holding AT_SETPOINT of the
commanded references for `hold` s, judged on the poll's statuses (drives/poll.py).

A poll that read the references from before the command (AT_SETPOINT of the old speeds), or a
drive in local control, does not start the hold; while the link is down the hold restarts, and
the wait goes on only once the reconnect has verified both drives. The wait asks the poll for
extra reads (drives/poll_pace.py): the first status at once or at `expect` (monotonic s, the
ramps' end), one every min(poll_interval / 4, hold / 10) until both are there, and one when the
hold would end. It raises what the poll found (its failure: a trip, a link loss; or its crash:
nobody watches the drives), or DriveTimeoutError after `timeout` s.
"""

from __future__ import annotations

import time

from drives import registers as R
from drives.errors import DriveError, DriveTimeoutError
from drives.poll import DrivePoll
from drives.poll_pace import SettleDetector
from drives.waits import first_set
from drives.state import RigDriveState


async def settled(poll: DrivePoll, *, hold: float, timeout: float, expect: float | None = None) -> RigDriveState:
    """The state once both drives have held the commanded references `hold` s (see above)."""
    detector = SettleDetector(hold)
    deadline = time.monotonic() + timeout
    last_poll, soon = -1, min(poll.poll_interval / 4, hold / 10)  # s between reads until both are there
    poll.pace.ask(first := time.monotonic() if expect is None else expect)  # the first status
    while True:
        tick = poll.tick
        if poll.failure is not None:
            raise poll.failure
        poll.alive()  # a crash is the failure too, unless one came before it (raised above)
        if poll.command is None:
            raise DriveError("no speeds commanded: call set_speeds() first")
        st, refs = poll.state, poll.command
        if st.polls != last_poll:
            last_poll = st.polls
            if not st.link_ok:
                detector.reset()
            elif detector.update(st.at_reference(refs), st.time):
                return st
            else:  # judged when the hold would end; not there yet: read again soon
                poll.pace.ask(detector.settles_at or max(st.time + soon, first))  # not before `first`
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            raise DriveTimeoutError(
                f"not at setpoint (AT_SETPOINT held {hold:g} s) within {timeout:g} s: " + st.describe(),
                register=R.SW,
            )
        await first_set(tick, timeout=remaining)
