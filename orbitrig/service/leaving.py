"""The service's way out when a run's disk does not return (mixin of
:class:`orbitrig.service.rig_service.RigService`; `orbitrig serve` calls it on a second shutdown
signal while the run waits for a disk that stalls (RunEngine.waiting_for_disk), and on the first
once the run has had its whole bounded wait).

The drives come first: nothing happens while the run still holds them (its closing stop is
bounded by the drives' stop timeout), nor while an emergency stop the service sends over its
own link is under way (at most idle_stop.SIGNAL_STOP_S). Then the run gets `grace` s to end on
its own; a run still waiting for its disk then is left: ``offline`` is published naming what
was not written (`RunEngine.unwritten`), and the caller ends the process. What was written
before is kept (every block, result and completion is its own file, written whole or not at
all); the run's folder keeps the status ``running`` and `orbitrig sweep --resume` continues it.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable

from drives.waits import first_set
from orbitrig.service import idle_stop
from orbitrig.service import protocol as proto
from orbitrig.service.engine_port import Engine
from orbitrig.service.link import BrokerLink

log = logging.getLogger("orbitrig.service.rig_service")

#: wall s a run past its drives' stop gets after a second signal to end on its own
LEAVE_GRACE_S = 2.0
#: wall s the run gets beyond the service's own wait for it (`run_end_timeout`) after one signal
CUT_GRACE_S = 10.0
#: wall s the offline status naming what was not written may take to reach the broker
OFFLINE_DRAIN_S = 2.0
#: wall s the broker connection may take to close cleanly before the process ends
DISCONNECT_S = 2.0
#: wall s between two looks at whether the run still holds the drives
HOLD_POLL_S = 0.05


class LeavingWithoutDisk:
    """The leaving side of the rig service (the attributes below are the service's)."""

    link: BrokerLink
    _engine: Engine | None
    _run_task: asyncio.Task | None
    _run_id: str | None
    _connection: asyncio.Task[None] | None = None  # the main broker connection's task (serve)
    idle_stops: Callable[[], set[asyncio.Task[idle_stop.Outcome]]]
    _run_end_timeout: Callable[[], float]
    _set_status: Callable[..., None]

    @property
    def run_waits_for_disk(self) -> bool:
        """The active run is past its drives' closing stop and waits for its disk (RunEngine.waiting_for_disk)."""
        task, engine = self._run_task, self._engine
        return task is not None and not task.done() and engine is not None and engine.waiting_for_disk

    @property
    def run_holds_drives(self) -> bool:
        """A run is active and not yet past its closing stop: a stop asked of it reaches the drives."""
        task, engine = self._run_task, self._engine
        return task is not None and not task.done() and engine is not None and not engine.let_go

    async def leave_without_disk(self, why: str, grace: float | None = None) -> str | None:
        """Once the drives are stopped (above), `grace` s (None: the service's wait for the run's end
        and CUT_GRACE_S) for the run to end; if it has not, ``offline`` published naming what the run
        did not write, and those words returned (the caller ends the process). None: no run was left."""
        while self.run_holds_drives:
            await asyncio.sleep(HOLD_POLL_S)
        if stops := self.idle_stops():
            await asyncio.wait(stops, timeout=idle_stop.SIGNAL_STOP_S)
        task, engine = self._run_task, self._engine
        if task is None or task.done() or engine is None:
            return None
        wait = self._run_end_timeout() + CUT_GRACE_S if grace is None else grace
        done, _ = await asyncio.wait({task}, timeout=wait)
        if done:
            return None
        words = left_unwritten(why, self._run_id, engine)
        log.error("%s", words)
        self._set_status(proto.OFFLINE, self._run_id, words)
        self.link.leaving = True
        if self.link.online.is_set() and await first_set(self.link.drained, timeout=OFFLINE_DRAIN_S) is None:
            log.warning("the offline status was not acknowledged within %.0f s", OFFLINE_DRAIN_S)
        if (connection := self._connection) is not None:  # a clean disconnect: no last will over these words
            connection.cancel()
            await asyncio.wait({connection}, timeout=DISCONNECT_S)
        return words


def left_unwritten(why: str, run_id: str | None, engine: Engine) -> str:
    """The words of a service leaving a run's disk: what was not written, what is kept."""
    items = ", ".join(engine.unwritten()) or "nothing"
    folder = engine.out_dir
    return (
        f"left without waiting for the disk ({why}), after the drives' closing stop; run {run_id} in {folder}: "
        f"not written: {items}; every file written before is kept: `orbitrig sweep --resume {folder}` continues it"
    )
