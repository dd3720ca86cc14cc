"""The run engine's one `finally` (mixin of `RunEngine`): every way out of a run stops both
drives first (an emergency ramp after an abort or a failure), then closes the links, then waits
for the storage and identification in flight, then records the run's end; each cleanup failure
is logged and the rest still runs. A run cancelled while it opened the rig (not by an abort,
whose sender stops the drives itself) sends both the emergency stop over a link of its own.

A disk that stalls holds the run in `stopping` after its drives are stopped: from
STORAGE_GRACE_S after the stop on, the stopping status says how the drives' stop ended and
names what the run waits for, again every STORAGE_NOTE_S ('drives: ramp stop (OFF1); standstill
after 1.2 s: ...; waiting for the storage in flight: store 0002/f03, complete point 0002 (for 30 s)').
`unwritten` names what a process that leaves without waiting for its disk did not write.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Mapping
from types import MappingProxyType
from typing import TYPE_CHECKING

from orbitrig.run.background import Background, to_the_end
from orbitrig.run.control import RunControl
from orbitrig.run.ending import aborted, record_the_end, while_stopping
from orbitrig.run.safe_stop import closing_stop, unconfirmed
from orbitrig.run.states import ABORTED, COMPLETED, FAILED, STOPPED, STOPPING, Outcome
from orbitrig.run.stop_words import send_stop_words

if TYPE_CHECKING:
    import asyncio

    from orbitrig.config import RigConfig
    from orbitrig.run.rig_io import RigAccess, RigIO
    from orbitrig.store.writer import RunStore

log = logging.getLogger("orbitrig.run.engine")

#: wall s the storage in flight may take after the drives' stop before the stopping status names it
STORAGE_GRACE_S = 1.0
#: wall s between two stopping statuses while the run waits for the storage in flight
STORAGE_NOTE_S = 30.0
#: wall s one storage write may take before the run is said to wait for a disk that stalls
DISK_STALL_S = 5.0
#: the last of what a run leaves unwritten until its end is recorded
END_RECORD = "the run's end (its status, run.h5)"


class RunClosing:
    """The closing part of `RunEngine`."""

    rig: RigConfig
    access: RigAccess
    run_id: str | None
    timing: dict[str, float]
    _control: RunControl
    _background: Background
    _io: RigIO | None
    _t0: float
    _let_go: bool
    _opening: asyncio.Task[RigIO] | None
    _log_event: Callable[..., None]
    _end_written = True  # False from a run's start until its end is recorded
    _planned: Mapping[int, int | None] = MappingProxyType({})  # the run's blocks per point (Plan.blocks)
    _disk_wait = False  # its storage in flight not finished STORAGE_GRACE_S after the drives' stop
    #: its drives' closing stop ended with both confirmed at standstill (a cancellation meanwhile
    #: does not cut it short: what a run cancelled in it says, orbitrig.service.run_handling)
    standstill_confirmed = False

    @property
    def waiting_for_disk(self) -> bool:
        """The run is past its drives' closing stop, waits for its storage in flight (its status
        says so) and one write of it has not returned for DISK_STALL_S: a disk that stalls, not an
        identification or a slow write (its end not recorded yet)."""
        stalled = self._background.write_stalled_s() >= DISK_STALL_S
        return self._disk_wait and stalled and not self._end_written

    def unwritten(self) -> list[str]:
        """What the run has not written yet, oldest first: its storage and identification in
        flight, then its end record; [] once its end is recorded."""
        return [] if self._end_written else [*self._background.in_flight(), END_RECORD]

    async def _make_safe(self, io: RigIO, store: RunStore, status: Outcome, message: str) -> tuple[Outcome, str]:
        """Every exit path: drives to a safe stop first, then the links, then storage; each
        failure logged, the rest still done. A failure is reported (state faulted) once the
        drives are safe. Returns the final (status, message): aborted after an abort while
        stopping; failed when the drives are not confirmed stopped, when storage in flight
        failed, or when the run's status and run.h5 could not be recorded."""
        self._disk_wait = False
        if self._control.state != STOPPING:
            self._control.fire("finish", message)
        status, message = await self._cleanup(io, status, message)
        self._io = None
        if self._control.abort_requested and status in (COMPLETED, STOPPED):  # an abort while stopping
            status, message = ABORTED, while_stopping(aborted(self._control), status, message)
        if status == FAILED:  # reported once the drives are safe
            self._control.fire("fail", message)
        self.timing["wall"] = time.monotonic() - self._t0
        # run.h5's consolidation and fsync, off the loop (the service answers meanwhile); each
        # failure logged as it happens, before run.log's last line
        # (a stopped or aborted run's message names the points it left incomplete: orbitrig.run.ending)
        # (with every point complete, as it ended, 'all points completed; stopped by ada', a cancellation's
        # too: orbitrig.run.ending)
        ended = await to_the_end(
            record_the_end, store, self.run_id, status, message, self._cleanup_failed, self._planned
        )
        self._end_written = True
        if ended[0] != status:  # its status or run.h5 could not be recorded
            self._control.fire("fail", ended[1])
        elif status != FAILED:
            self._control.fire("done", f"run {self.run_id} {status}: {ended[1]}")
        await to_the_end(store.run_log.flush)  # run.log holds every line of the run when it returns
        return ended

    async def _cleanup(self, io: RigIO, status: Outcome, message: str) -> tuple[Outcome, str]:
        """Both drives stopped and confirmed at standstill, then the links closed, then the storage
        in flight finished: (status, message), failed if the stop or the storage was not done, or
        if a drive tripped during the stop (orbitrig.run.safe_stop.closing_stop)."""
        said = ["no drive was opened"]

        def note(line: str) -> None:
            said.append(line)
            self._log_event(line)

        self.standstill_confirmed = False
        if io.drives is not None:
            said.append("drives not confirmed stopped")  # unless the stop's line follows
            timeout = self.access.time_scale.wall(self.rig.drives.stop_timeout_s) + 5.0
            status, message, self.standstill_confirmed = await closing_stop(
                io.drives, self._control.aborted, (status, message), timeout, note, self._cleanup_failed
            )
        elif self._opening_cut():
            status, message = await self._stop_unopened(status, message, note)
        self._let_go = True  # a stop asked from here on is not the run's to carry to the drives
        for what, action in (
            ("close the rig links", lambda: io.__aexit__(None, None, None)),
            ("finish the storage in flight", lambda: self._storage_settled(said[-1])),
        ):
            try:
                await action()
            except BaseException as err:  # noqa: BLE001 - every cleanup step must run
                self._cleanup_failed(what, err)
        failed = self._background.failure_message()
        if failed is not None and status in (COMPLETED, STOPPED):  # points completed before it are kept
            status, message = FAILED, failed
        return status, message

    def _opening_cut(self) -> bool:
        """The run's own cancellation cut its opening of the rig short (not an abort's: whoever
        aborts a run still opening stops the drives over a link of its own, orbitrig.service.idle_stop)."""
        opening = self._opening
        return opening is not None and opening.cancelled() and not self._control.abort_requested

    async def _stop_unopened(self, status: Outcome, message: str, note: Callable[[str], None]) -> tuple[Outcome, str]:
        """The run cancelled while it opened the rig: the drives' entry let go of their link at once
        (drives/entry.py), so both get the emergency stop (a cancellation is an abort) over a link of
        the run's own (orbitrig.run.stop_words): drives found turning there, or not read yet, do not
        run on. (status, message): failed, 'drives not confirmed stopped', if a drive did not take it."""
        try:
            sent = await send_stop_words(self.access.endpoints.modbus_url, self.rig.drives, emergency=True)
        except Exception as err:  # noqa: BLE001 - every cleanup step must run
            self._cleanup_failed("send the drives the emergency stop", err)
            return unconfirmed(status, message, err)
        took = ", ".join(sent.took) or "no drive"
        note(
            f"drives: emergency stop (OFF3) over a link of the run's own, its opening cut short; taken by {took}; "
            "standstill not confirmed (that link sends the stop, it does not watch the drives)"
        )
        return unconfirmed(status, message, sent.errors[0]) if sent.errors else (status, message)

    async def _storage_settled(self, drives: str) -> None:
        """Until the storage and identification in flight have finished; while they have not
        (after STORAGE_GRACE_S, then every STORAGE_NOTE_S), the stopping status says `drives`
        (how their stop ended) and what the run waits for, for how long."""
        t0, wait = time.monotonic(), STORAGE_GRACE_S
        while not await self._background.settle(wait):
            self._disk_wait, wait = True, STORAGE_NOTE_S
            names = ", ".join(self._background.in_flight())
            if self._control.state == STOPPING:
                waited = time.monotonic() - t0
                self._control.fire(
                    "finish", f"{drives}; waiting for the storage in flight: {names} (for {waited:.0f} s)"
                )

    def _cleanup_failed(self, what: str, err: BaseException) -> None:
        """Log a failed cleanup step (also called from the storage thread: logging and the
        store's log rows and run.log are safe there; no event is emitted)."""
        log.error("cleanup: cannot %s: %s: %s", what, type(err).__name__, err)
        self._log_event(f"cleanup: cannot {what}: {err}")
