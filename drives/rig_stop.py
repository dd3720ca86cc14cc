"""The stop commands of both drives (drives/rig.py's RigDrives, whose part this is): `stop` (a ramp
stop or an emergency stop, waiting for standstill), `stop_now` (the stop words at once, an abort's
first act) and `_safe_stop`, the one way every stop of the rig goes out (its entry's, exit's, a
failed start's): delivered even while the caller is cancelled, sent through the poll (drives/owed.py).
"""

from __future__ import annotations

import asyncio
import time
from typing import TYPE_CHECKING

from drives.errors import DriveError
from drives.ramp_down import standstill_wait
from drives.stop import Quiet, loud
from drives.stop_again import send_until_taken
from drives.stop_said import missed_stop, stop_kind
from drives.stop_wait import wait_stopped

if TYPE_CHECKING:
    from drives.drive import Drive
    from drives.poll import DrivePoll
    from drives.stop import StopSender


class RigStop:
    """RigDrives' stop commands (its base: the attributes below are RigDrives', see there)."""

    spin: Drive
    orbit: Drive
    poll_interval: float
    _drives: tuple[Drive, Drive]
    _stops: StopSender
    _poll: DrivePoll
    _poll_task: asyncio.Task[None] | None
    _emergency: bool  # the last stop was an emergency stop: the exit repeats it
    _sent_emergency: bool  # the last stop command's word as sent is OFF3
    stop_errors: list[DriveError]  # delivery failures of the last stop command
    stop_sent: str  # the last stop command's words as sent ('ramp stop (OFF1)', stop_kind)
    stop_again: str  # what its word sent again did ('' if it went once: drives/stop_again.py)

    async def stop(self, *, emergency: bool = False, wait: bool = True, timeout: float | None = None) -> None:
        """Ramp both drives to zero (OFF1), or emergency-stop them (OFF3).

        Sends the stop to both drives even if one fails (the stop is owed, drives/poll.py); after an
        emergency stop since the last speed command it is one too (drives/owed.py; `stop_sent`,
        StopTripError name it). With `wait`, a word not taken for a reason that may pass goes again until taken
        or the wait is out (drives/stop_again.py, said in `stop_again`); returns once both read an actual speed
        of zero; `timeout` (s) defaults to the drives' own ramp time (of the stop sent: OFF3's emergency ramp)
        from the present speed plus a margin. A drive that trips meanwhile (not known tripped at the command)
        raises StopTripError at standstill or once the wait ends. A drive that did not take the stop raises its
        delivery error after the wait for the one that took it, ended with what that one did (`missed_stop`).
        """
        self._require_open()
        self._emergency, t_cmd, known = emergency, time.monotonic(), self._poll.known_trips()
        errors, self.stop_again = await self._safe_stop(emergency=emergency), ""
        if wait:
            if timeout is None:  # sized from the word sent (OFF3 after an emergency stop), not the one asked
                now = ((self.spin, self._poll.state.spin), (self.orbit, self._poll.state.orbit))
                timeout = standstill_wait(now, emergency=self._sent_emergency, poll_interval=self.poll_interval)
            errors, self.stop_again = await send_until_taken(
                lambda: self._sent_again(emergency), errors, self._drives, t_cmd + timeout
            )
        took = frozenset(d.device_id for d in self._drives) - {err.drive for err in errors}
        if wait and took and timeout is not None:  # the drive that took it is waited for, if the other did not
            try:
                await wait_stopped(self._poll, known, t_cmd, timeout, stop=self.stop_sent, of=took if errors else None)
            except DriveError as err:
                if errors:
                    raise missed_stop(errors[0], self._drives, took, err) from err
                raise
        if errors:
            raise missed_stop(errors[0], self._drives, took, None) if wait and took else errors[0]

    def stop_now(self, *, emergency: bool = True) -> asyncio.Task[list[DriveError]]:
        """Send the stop to both drives now, ahead of every request waiting for the link, without
        waiting for the caller to unwind (an abort's first act); the task's result: the delivery
        errors. `stop()` afterwards repeats it and waits for standstill."""
        self._require_open()
        self._emergency = self._emergency or emergency
        return self._poll.send_stop(emergency=emergency)

    def _require_open(self) -> None:
        if self._poll_task is None:
            raise DriveError("RigDrives is not open: use `async with RigDrives(...)`")

    async def _sent_again(self, emergency: bool) -> list[DriveError]:
        """The stop sent again by `stop` (drives/stop_again.py): a drive held at its keypad that
        refuses it is said at the pace of the poll's stop sent again (drives/local_hold.py, the one
        owner of those words: once as the hold starts, every 30 s, once when it takes the stop), not
        with an ERROR per send."""
        holds = self._poll.holds
        errors = await self._safe_stop(emergency=emergency, quiet=holds.quiet)
        holds.outcome(errors, self.stop_sent)
        return errors

    async def _safe_stop(self, *, emergency: bool = False, quiet: Quiet = loud) -> list[DriveError]:
        """Deliver the stop to both drives even if the calling task is cancelled meanwhile.

        Returns the delivery errors (logged; those `quiet` says are said already at DEBUG); a
        cancellation that arrived during the stop is re-raised once the stop has been sent.
        """
        task = self._poll.send_stop(emergency=emergency, quiet=quiet)  # after a stop under way, never interleaved
        cancelled = False
        while not task.done():
            try:
                await asyncio.shield(task)
            except asyncio.CancelledError:
                cancelled = True
        self._sent_emergency = self._stops.emergency(task)
        self.stop_errors, self.stop_sent = task.result(), stop_kind(self._sent_emergency)
        if cancelled:
            raise asyncio.CancelledError
        return self.stop_errors
