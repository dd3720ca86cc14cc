"""Interlock supervision: a task of its own that tells the engine when a trip starts or clears.

The sensors are read as states (the CAN node's latest values, the drives'
latest poll), so the supervisor samples them every `period` s and turns
them into events: a *fail* trip calls `on_fail` once (the engine ends the
run); a *suspend* trip sets `tripped` until it clears (then `clear` is set).
The engine never polls: it waits on these events.

A CAN node lost or mute (no heartbeat, not operational, no pressure or status
frames, a sensor fault) suspends the run only for `can_heartbeat_timeout_s`; the
supply pump off or the supply below its minimum only for `supply_lost_timeout_s`
(wall s, counted from the first sample that saw it, whatever the engine is doing
meanwhile: settling, paused, waiting for a confirmation): then it becomes a fail
trip and the drives stop.

A sample that raises (a bug in a sensor read or a check) is logged with its
traceback and made a fail trip ("supervision"): the run never goes on with its
interlocks unwatched. A failure the drive poll recorded (one that failed on a bug, a failed
verification after a link loss: `RigIO.drives_judged` raises it; the poll has ramped both drives
to zero, drives/poll.py) is a fail trip in the poll's words ("drive poll").
"""

from __future__ import annotations

import asyncio
import logging
import time
from typing import Callable

from daq.aux import AuxState
from drives.errors import DriveError
from drives.state import RigDriveState
from orbitrig.config import Interlocks
from orbitrig.run import interlocks
from orbitrig.run.interlocks import NODE_KINDS, SUPPLY_KINDS, Trip

log = logging.getLogger(__name__)


class InterlockSupervisor:
    def __init__(
        self,
        read: Callable[[], tuple[AuxState | None, RigDriveState | None]],
        cfg: Interlocks,
        on_fail: Callable[[Trip], None],
        *,
        period: float = 0.05,
    ):
        self._read = read
        self.cfg = cfg
        self._on_fail = on_fail
        self.period = period
        self.pressure_armed = False  # the point's pressures verified: supply watched at standstill too
        self.trip: Trip | None = None  # the suspension in force
        self.failure: Trip | None = None
        self.tripped = asyncio.Event()
        self.clear = asyncio.Event()
        self.clear.set()
        self._since: dict[frozenset[str], float] = {}  # escalating group -> its first sample in force

    def trips(self) -> list[Trip]:
        aux, drives = self._read()
        return interlocks.check(aux, drives, self.cfg, pressure_armed=self.pressure_armed)

    def sample(self) -> None:
        """Look once; fire the events that changed."""
        trips = self._escalated(self.trips())
        fail = next((t for t in trips if t.action == interlocks.FAIL), None)
        if fail is not None and self.failure is None:
            self.failure = fail
            self._on_fail(fail)
        suspend = next((t for t in trips if t.action == interlocks.SUSPEND), None)
        self.trip = suspend
        if suspend is not None:
            self.clear.clear()
            self.tripped.set()
        else:
            self.tripped.clear()
            self.clear.set()

    def _escalated(self, trips: list[Trip]) -> list[Trip]:
        """`trips`, with a fail trip ahead for each escalating group in force longer than its limit."""
        cfg, now, fails = self.cfg, time.monotonic(), []
        for kinds, limit in ((NODE_KINDS, cfg.can_heartbeat_timeout_s), (SUPPLY_KINDS, cfg.supply_lost_timeout_s)):
            first = next((t for t in trips if t.kind in kinds), None)
            if first is None:
                self._since.pop(kinds, None)
                continue
            since = self._since.setdefault(kinds, now)
            if now - since >= limit:
                fails.append(Trip(first.kind, interlocks.FAIL, _lasting(first, limit)))
        return fails + trips

    def look(self) -> bool:
        """Sample once; a sample that raises is a fail trip. Whether a fail trip is recorded (the
        engine's last look when the run fails: what caused the failure is said as the interlock)."""
        if self.failure is not None:
            return True
        try:
            self.sample()
        except DriveError as err:  # what the drive poll recorded (RigIO.drives_judged): no bug of ours
            self.failure = Trip(interlocks.TripKind.DRIVE_POLL, interlocks.FAIL, f"drive poll: {err}")
            self._on_fail(self.failure)
        except Exception as err:  # a bug must not leave the interlocks unwatched
            log.exception("interlock supervision failed")
            self.failure = Trip(
                interlocks.TripKind.SUPERVISION,
                interlocks.FAIL,
                f"interlock supervision failed ({type(err).__name__}: {err}): the interlocks are not watched",
            )
            self._on_fail(self.failure)
        return self.failure is not None

    async def watch(self) -> None:
        """`look` every `period` s until a fail trip."""
        while not self.look():
            await asyncio.sleep(self.period)


def _lasting(trip: Trip, limit: float) -> str:
    """`trip`'s condition said as lasting more than `limit` s."""
    if trip.kind == interlocks.TripKind.CAN_HEARTBEAT:  # the trip says why: no heartbeat, or its bus link failed
        why = trip.message.removeprefix(f"{interlocks.NODE_LOST} (").removesuffix(")")
        return f"{interlocks.NODE_LOST} for more than {limit:g} s ({why}): supply pressure and pump are not watched"
    return f"{trip.message} for more than {limit:g} s"
