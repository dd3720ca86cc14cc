"""What ends a calibration step while the drives turn (the checks of `CalibrationSession`, a mixin):
the drives' poll (a drive tripped, the Modbus link lost) and the run's interlocks, each
`CalibrationFailed` naming what failed; `watched` races a hold, an acquisition or a prompt against
them. An interlock that suspends a sweep and drops its block (the lubricant supply lost, the CAN
sensor node lost or mute) ends the step at once: a record holds no reading taken without supply or
without the node's interlocks. SI throughout."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Awaitable
from typing import TYPE_CHECKING, Callable, TypeVar

from drives.errors import DriveError
from orbitrig.config import RigConfig
from orbitrig.errors import OrbitrigError
from orbitrig.run.interlocks import NODE_KINDS, SUPPLY_KINDS, Trip
from orbitrig.run.rig_io import RigIO
from orbitrig.run.supervision import InterlockSupervisor
from rigunits import rpm_text

if TYPE_CHECKING:
    from orbitrig.run.calibration import SlowRoll

log = logging.getLogger("orbitrig.run.calibration")
T = TypeVar("T")


class CalibrationFailed(OrbitrigError):
    """A calibration step could not be completed (drives, A/D link, operator)."""


class CalibrationChecks:
    """The checks of :class:`orbitrig.run.calibration.CalibrationSession` (a mixin: the
    attributes below are the session's)."""

    rig: RigConfig
    io: RigIO
    interlocks: InterlockSupervisor
    roll_spec: SlowRoll | None
    at_standstill: bool
    commanded: bool

    def check_drives(self) -> None:
        """CalibrationFailed if the drives' poll found a drive tripped (recorded once the poll has
        commanded both to stop, drives/poll.py) or failed otherwise (`RigDrives.check`), or declared
        the Modbus link to them lost (`link_ok`, as the sweep's drive interlock): the message names
        the drive and its fault code, or the lost link and the request that went unanswered; then
        the interlocks (`check_interlocks`)."""
        drives = self.io.drives
        if drives is None:
            return
        try:
            drives.check().require_link()
        except DriveError as err:
            raise CalibrationFailed(f"{err}{self._during()}") from err
        self.check_interlocks()

    def check_interlocks(self) -> None:
        """CalibrationFailed naming the interlock if one has failed (orbitrig.run.supervision: a
        drive tripped or its link lost), as it fails a sweep; or if one is in force that suspends a
        sweep and drops its block (the supervisor's `trip`, the sweep's rule: orbitrig.run.
        interlock_guard): the lubricant supply lost (SUPPLY_KINDS: pump off, below its minimum) or
        the CAN sensor node lost or mute (NODE_KINDS). A record holds no reading taken without supply
        or without the node's interlocks; the step ends at once (the session's emergency stop), not
        after supply_lost_timeout_s or can_heartbeat_timeout_s. Any other suspension (a calibration
        step does not arm the supply band's upper edge) ends it too, worded as the interlock it is."""
        trip = self.interlocks.failure
        if trip is not None:
            raise CalibrationFailed(f"interlock: {trip.message}{self._during()}")
        held = self.interlocks.trip
        if held is None:
            return
        if held.kind in NODE_KINDS:
            raise CalibrationFailed(
                f"interlock: {held.message}{self._during()}: no calibration without the node's interlocks"
            )
        if held.kind in SUPPLY_KINDS:
            raise CalibrationFailed(
                f"interlock: {held.message}{self._during()}: no calibration without the lubricant supply"
            )
        raise CalibrationFailed(
            f"interlock: {held.message}{self._during()}: no calibration while an interlock holds the rig ({held.kind})"
        )

    def _during(self) -> str:
        """' during the slow roll at spin ..., orbit ...' while a roll's spindles were commanded to
        turn and not confirmed at standstill since; else nothing (no spindle started yet)."""
        roll = self.roll_spec
        if roll is None or not self.commanded or self.at_standstill:
            return ""
        return f" during the {roll.name} at spin {rpm_text(roll.spin)}, orbit {rpm_text(roll.orbit)}"

    async def watched(self, work: Callable[[], Awaitable[T]], check: Callable[[], None] | None = None) -> T:
        """``await work()`` (a hold, an acquisition, a prompt) raced against the drives' poll and
        the interlocks: `check` (default `check_drives`) before it starts, every poll interval
        (wall s) while it runs and once it is done; a trip, a lost link or a failed interlock
        cancels it and raises CalibrationFailed (the session's way out then stops both drives)."""
        check = check or self.check_drives
        check()
        period = self.io.drives.poll_interval if self.io.drives is not None else 0.1
        task = asyncio.ensure_future(work())
        try:
            while not task.done():
                await asyncio.wait({task}, timeout=period)
                check()
            return task.result()
        finally:
            if not task.done():
                task.cancel()
                await asyncio.wait({task})
            if not task.cancelled():
                task.exception()  # retrieved: a failure of the work cut short is not logged as unhandled


def interlock_failed(trip: Trip) -> None:
    """A fail trip during a calibration step: the step's next check raises it (`check_interlocks`)."""
    log.error("interlock: %s", trip.message)
