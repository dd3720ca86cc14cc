"""What the poll's stops reached: a stop owed, a stop held (`OwedStops`, owned by DrivePoll).

Every stop of the rig and of its poll is sent through `OwedStops.send`. One that some drive did
not take is owed (`owed`; True: an emergency stop is owed, and stays so) until a later stop
reaches both drives or a new speed is commanded; a stop asked before the last speed command owes
nothing. A stop both drives took holds until a new speed is commanded. `problem` judges a poll's
statuses against them, with no speed commanded: a drive found running, or with a nonzero REF,
while a stop is owed (the owed stop goes again), or running again after a stop both took (someone
else started it: the held stop goes again); reads from before that stop ended show nothing.
Once an emergency stop (OFF3) has been asked, every stop after it is one too until a new speed is
commanded (the poll's for a trip in the emergency ramp, its crash's, the rig's exit): a ramp stop
(OFF1) after it would turn a drive's emergency ramp back into its ten times slower ramp stop. So is
every stop once a drive has been read in its emergency ramp on entry (`emergency_found`: one sent
before, by an earlier owner or another client).
"""

from __future__ import annotations

import asyncio
import functools
import logging
import time
from collections.abc import Sequence

from drives.drive import DriveStatus
from drives.errors import DriveError
from drives.findings import running_after_stop, running_while_owed
from drives.starve import Starver
from drives.emergency_sent import speeds_commanded
from drives.stop import Quiet, StopSender, loud

log = logging.getLogger(__name__)


class OwedStops:
    """The stops sent through one StopSender and what they reached since the last speed command.

    owed : a stop some drive did not take (True: an emergency stop), None if none.
    sending : stops under way (what they reached is not known yet).
    """

    def __init__(self, stops: StopSender, starver: Starver):
        self._stops, self._starver = stops, starver
        stops.lifts = starver.lifting  # an emergency stop word reaches a starved drive (drives/starve.py)
        self.owed: bool | None = None
        self._owed_at = 0.0  # monotonic s the owed stop ended: statuses read before it show nothing
        self.sending = 0
        self.ended_at = 0.0  # monotonic s the last stop ended
        self._epoch = 0  # speed commands so far: a stop asked before the last one owes nothing
        self._held: tuple[float, bool] | None = None  # (monotonic s, emergency) of a stop both took, none since
        self._emergency = False  # an emergency stop asked since the last speed command: every stop is one

    def commanded(self) -> None:
        """A speed was commanded: no stop is owed or held any more, no emergency stop sent before
        is under way (drives/stop.py)."""
        self._epoch += 1
        speeds_commanded(self._stops.drives)
        self.owed, self._held, self._emergency = None, None, False

    def emergency_found(self) -> None:
        """A drive read in its emergency ramp (a stop sent before this owner's, another client's):
        every stop is the emergency stop until a speed is commanded, as after one asked here."""
        self._emergency = True

    def send(self, emergency: bool, quiet: Quiet = loud) -> asyncio.Task[list[DriveError]]:
        """Send the stop (OFF1, `emergency`: OFF3) to both drives through the StopSender; its
        task's result: the delivery errors (`quiet`: those said already, StopSender.send). Owed until
        a stop is delivered to both. After an emergency stop asked since the last speed command it is one too."""
        emergency = self._emergency = emergency or self._emergency
        self.sending += 1
        task = self._stops.send(emergency=emergency, quiet=quiet)
        task.add_done_callback(functools.partial(self._ended, self._epoch))
        return task

    def _ended(self, epoch: int, task: asyncio.Task[list[DriveError]]) -> None:
        """A stop's outcome: taken by both drives, nothing is owed; else the stop is owed (an
        emergency stop owed stays owed as such) unless a speed was commanded since it was asked.
        Which stop it was: the word it sent (`StopSender.emergency`), as its findings say it."""
        self.sending -= 1
        self.ended_at = time.monotonic()
        if epoch != self._epoch:
            return
        emergency = self._stops.emergency(task)
        self._starver.stop_ended()
        if not task.cancelled() and task.exception() is None and not task.result():
            self.owed, self._held = None, (time.monotonic(), emergency or bool(self._held and self._held[1]))
            return
        self.owed = bool(self.owed) or emergency
        self._owed_at = time.monotonic()

    def again(self) -> bool:
        """Whether the stop sent again is the emergency stop: one owed, or (none owed) the one held."""
        return bool(self.owed) if self.owed is not None else bool(self._held and self._held[1])

    def problem(self, statuses: Sequence[DriveStatus], *, commanded: bool, why: str = "") -> DriveError | None:
        """With no speed `commanded` and a stop owed: the first drive found running, or with a
        nonzero REF, in `statuses` (all read after the owed stop ended), as the failure to record;
        with a stop held: the first found running again after it. None if there is none; drives
        found neither running nor with a REF owe nothing more."""
        if commanded or self.sending:
            return None
        if self.owed is None:  # a stop both took: a drive running again was started by someone else
            held = self._held
            return (
                None
                if held is None or any(st.time <= held[0] for st in statuses)
                else (running_after_stop(statuses, emergency=held[1], why=why))
            )
        if any(st.time <= self._owed_at for st in statuses):
            return None
        problem = running_while_owed(statuses, emergency=self.owed, why=why)
        if problem is None:
            log.info("the stop owed is not needed any more: both drives found stopping or stopped")
            self.owed = None
        return problem
