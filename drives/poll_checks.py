"""What each poll of both drives checks in the statuses it read (drives/poll.py's DrivePoll, whose
part this is): a trip, the drives off the command once they followed it, a stop owed or held, a
late word of ours read back, a drive running on through the stop sent again.

- Every stop goes through `send_stop` (or the poll's own) to drives/owed.py (`OwedStops`): one
  that some drive did not take is owed (`owed`) until a later stop reaches both drives or a new
  speed is commanded. A poll (after a reconnect or not) that finds a drive running, or with a
  nonzero REF, while no speed is commanded and a stop is owed sends the owed stop again (the
  emergency stop if an emergency stop is owed) and records the failure. A stop both drives took
  holds until a new speed is commanded: a drive found running again after it (another client,
  its keypad) gets it again, and the failure is recorded.
- A drive that runs on through the stop sent again (refused, or taken and ignored; the poll's
  requests feed its watchdog) gets no request until its comm-loss watchdog has tripped it, the
  other polled on; then its read says if that stopped it (drives/starve.py). Each is a failure.
  One that took the emergency stop let through to it meanwhile is read while it slows in its
  emergency ramp, so its standstill is seen (a stop's wait).
- A drive read after a stop running or at a nonzero REF while a write the link gave up on before
  it may still arrive (drives/late.py) gets the stop again, warned; not a failure. One found off
  its run command while a stop's word given up may still arrive, and reads it back, a poll's or
  the verification's after a reconnect, is said to have stopped on that late word
  (`stopped_late`): both stopped, the failure recorded, as above. After an emergency stop, a
  drive read still turning with the ramp stop word (OFF1) in CW gets the emergency stop again,
  warned (drives/emergency_kept.py): not a failure.
- A drive that refuses the stop sent again in local control (its keypad has it) gets it again at
  every poll all the same; that is said when it starts, every STILL_HELD_S s while it holds, and
  once when it ends (drives/local_hold.py), not at every poll.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Sequence
from typing import TYPE_CHECKING

from drives.emergency_kept import off3_released
from drives.errors import DriveError
from drives.findings import trip_fault
from drives.local_hold import LocalHolds
from drives.late import late_found, off_command_late, stopped_late
from drives.state import off_command
from drives.stop_said import stop_kind

if TYPE_CHECKING:
    from drives.drive import Drive, DriveStatus
    from drives.link import ModbusLink
    from drives.owed import OwedStops
    from drives.starve import Starver

log = logging.getLogger("drives.poll")  # the poll's messages keep its logger's name


class PollChecks:
    """The checks of DrivePoll's statuses (its base: the attributes below are DrivePoll's, see there)."""

    link: ModbusLink
    drives: tuple[Drive, Drive]
    command: tuple[int, int] | None
    following: bool
    failure: DriveError | None
    stopping_for: DriveError | None
    starver: Starver
    _owed: OwedStops
    holds: LocalHolds
    _trip_handled: bool
    _ack_time: float
    _started_at: float | None

    @property
    def owed(self) -> bool | None:
        """A stop some drive did not take (True: an emergency stop), None if none (drives/owed.py)."""
        return self._owed.owed

    def fail(self, err: DriveError) -> None:
        """Record `err` unless an earlier failure is still unacknowledged."""
        if self.failure is None:
            self.failure = err

    async def _check_owed(self, statuses: Sequence[DriveStatus]) -> None:
        """A drive found running while a stop is owed, or again after one held (drives/owed.py):
        the stop again, and the failure. Every poll with no speed commanded goes to the starver
        (one that runs on)."""
        if self.command is None and not self._owed.sending and self._owed.again():  # OFF3 kept (not OFF1)
            kept = off3_released(statuses, self.link.late, self._owed.ended_at)
            for words in kept:
                log.warning("%s", words)
            if kept:
                await asyncio.shield(self._owed.send(True))
                return
        if self.command is None and not self._owed.sending:  # a write given up reached a drive after the stop
            late = late_found(statuses, self.link.late, self._owed.ended_at, stop_kind(self._owed.again()))
            for words in late:
                log.warning("%s", words)
            if late:
                await asyncio.shield(self._owed.send(self._owed.again()))
                return
        problem = self._owed.problem(statuses, commanded=self.command is not None)
        took = self.owed is None  # a stop both took, held
        if problem is not None:  # one held in local control: said at its start, then every STILL_HELD_S s
            log.log(logging.DEBUG if self.holds.known(problem) else logging.ERROR, "%s", problem)
            task = self._owed.send(self._owed.again(), quiet=self.holds.quiet)
            errors = await asyncio.shield(task)
            self.holds.outcome(errors, stop_kind(self._owed.again()))
            self.fail(problem)
        elif self.owed is None:
            self.holds.not_owed()
        for found in self.starver.judge(statuses, took=took) if self.command is None else []:
            self.fail(found)  # one that runs on through the stops: its watchdog starved

    async def _check_trips(self, statuses: list[DriveStatus]) -> None:
        tripped = [st for st in statuses if st.tripped and st.time > self._ack_time]
        if not tripped:
            if not any(st.tripped for st in statuses):
                self._trip_handled = False
            return
        if self._trip_handled:
            return
        self._trip_handled = True
        await self._stop_and_fail(trip_fault(tripped[0]))

    async def check_following(self, statuses: Sequence[DriveStatus]) -> None:
        """Once a poll found both drives running at `command`, or the start confirmed both
        (`started`) before these statuses (a poll's, or a new start's) were read, a drive found no
        longer running, in local control or at another reference (stopped or moved by another
        client, or at the drive) is handled as a trip. Before that, a drive may still read as before."""
        if self.command is None:
            return
        problem = off_command(statuses, self.drives, self.command, self._stopped_late)
        if problem is None:
            self.following = True
            return
        started = self._started_at is not None and all(st.time > self._started_at for st in statuses)
        if self.following or started:
            self.following, self._started_at = False, None
            await self._stop_and_fail(off_command_late(problem, statuses, self.link.late))

    def _stopped_late(self, st: DriveStatus) -> str | None:
        """off_command's cause: a late stop word of ours read back (drives/late.stopped_late)."""
        return stopped_late(st, self.link.late)

    async def _stop_and_fail(self, err: DriveError) -> None:
        log.error("%s; ramping both drives to zero", err)
        self.stopping_for = err  # a start asked meanwhile raises it: it does not undo the stop
        try:
            await asyncio.shield(self._owed.send(bool(self.owed)))  # delivered before anyone hears of the fault
        finally:
            self.stopping_for = None
        self.command = None
        self.fail(err)
