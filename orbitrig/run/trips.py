"""What ends a run at once (mixin of `RunEngine`): an interlock's fail trip, a helper task of the
run (interlock watcher, log monitor) that raised, a storage write (disk full included) or an
identification that failed. Each cancels the run's body; the drives stop in the cleanup
(orbitrig.run.closing)."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable

from orbitrig.run import interlocks
from orbitrig.run.background import Background
from orbitrig.run.control import RunControl
from orbitrig.run.interlocks import Trip
from orbitrig.run.states import Outcome

log = logging.getLogger("orbitrig.run.engine")


class RunTrips:
    """The trips of `RunEngine`: the callbacks its supervisor, helpers and background call."""

    _control: RunControl
    _background: Background
    _body: asyncio.Task[Outcome] | None
    _failure: Trip | None
    _log_event: Callable[..., None]

    def _interlock_failed(self, trip: Trip) -> None:
        """A fail trip: the run ends at once (drives stopping in the cleanup). After an
        abort the drives are being stopped already: the trip is logged, the run ends aborted."""
        if self._control.abort_requested and self._failure is None:
            self._log_event(f"interlock while aborting (the drives are stopping): {trip.message}")
            return
        self._failure = trip
        self._log_event(f"interlock: {trip.message}")
        if self._body is not None and not self._body.done():
            self._body.cancel()

    def _helper_ended(self, task: asyncio.Task[None]) -> None:
        """A helper of the run (interlock watcher, log monitor) raised: logged with its traceback,
        the run fails at once (drives stopping in the cleanup); it never goes on unwatched."""
        if task.cancelled() or (err := task.exception()) is None:
            return
        log.error("run helper %s failed", task.get_name(), exc_info=err)
        message = f"the {task.get_name()} task failed ({type(err).__name__}: {err}): the run is not watched"
        if self._failure is not None:
            self._log_event(message)
            return
        self._interlock_failed(Trip(interlocks.TripKind.RUN_HELPER, interlocks.FAIL, message))

    def _background_failed(self, err: BaseException) -> None:
        """A storage write (disk full included) or an identification failed: the run ends at once."""
        self._log_event(self._background.failure_message() or str(err))
        if self._body is not None and not self._body.done():
            self._body.cancel()
