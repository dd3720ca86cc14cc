"""The run engine: one engine owns the drives and runs a plan (bluesky style).

`RunEngine.run(plan)` opens the rig (`RigIO` at the endpoints of its
`RigAccess`), starts the interlock supervisor and the CAN/drive log monitor,
and executes the plan's steps through the point procedure. Its state changes
only through the table of `orbitrig.run.states`; the operator's requests and
the waits are `orbitrig.run.control`'s.

Every exit path goes through one `finally` (`_make_safe`): both drives stop
first (an emergency ramp after an abort or a failure), then the links close,
then the storage in flight finishes and the run file gets its status; each
cleanup failure is logged and the rest still runs. A stop (operator, policy,
unanswered wait) therefore never waits for storage, and a storage failure
(disk full included) stops the drives before anything else. A stop that is not
delivered or not confirmed at standstill ends the run failed ("drives not
confirmed stopped"); so does a drive that trips during it ("drive tripped during
the closing stop", orbitrig.run.safe_stop; an abort stays an abort), and a helper
task (interlock watcher, log monitor) that raises, at once. A run that fails as it starts,
its folder created (its free-space check failing on another error than a full disk), goes
the same way: nothing opened, its end recorded (failed, the cause), the engine free again. The engine does no
terminal I/O: it publishes events to subscribers (the terminal UI of `orbitrig
sweep`, MQTT in `orbitrig serve`; orbitrig.run.announce). What ends a run at once: orbitrig.run.trips.
"""

from __future__ import annotations

import asyncio
import functools
import logging
import time
from pathlib import Path
from types import MappingProxyType
from typing import Callable

from daq.revolutions import Revolution

from orbitrig.config import MatrixConfig, RigConfig, warning_lines
from orbitrig.errors import OrbitrigError
from orbitrig.run.announce import RunAnnouncements
from orbitrig.run.background import Background
from orbitrig.run.closing import RunClosing
from orbitrig.run.control import RunControl, StopRun
from orbitrig.run.ending import aborted, stopped
from orbitrig.run.events import (  # noqa: F401 - the engine's public names
    Event,
    NoteEvent,
    NoteKind,
    ProgressEvent,
    ResultEvent,
    RunFailed,
    RunOutcome,
    Severity,
    StatusEvent,
    Subscriber,
)
from orbitrig.run import store_notes
from orbitrig.run.interlocks import Trip
from orbitrig.run.log_rows import monitor
from orbitrig.run.modbus_log import pymodbus_into
from orbitrig.run.plan import Plan, make_plan
from orbitrig.run.procedure import PointProcedure, RunParts, last_safe_point
from orbitrig.run.progress import ProgressMeter
from orbitrig.run.states import RunCommand
from orbitrig.run.requests import OperatorRequests
from orbitrig.run.rig_io import RigAccess, RigIO
from orbitrig.run.run_dir import completed_points, no_room, open_store, resume_events, run_age
from orbitrig.run.run_dir import started_order as _started_order
from orbitrig.run.states import (
    ABORTED,
    ALL_COMPLETED,
    COMPLETED,
    FAILED,
    FAULTED,
    IDLE,
    STOPPED,
    ConfirmMode,
    Outcome,
    RunState,
)
from orbitrig.run.supervision import InterlockSupervisor
from orbitrig.run.trips import RunTrips
from orbitrig.store.estimate import plan_bytes
from orbitrig.store.errors import StorageError, StorageFullError
from orbitrig.store.layout import point_name
from orbitrig.store.writer import RunStore

log = logging.getLogger(__name__)


class RunEngine(OperatorRequests, RunClosing, RunTrips, RunAnnouncements):
    def __init__(
        self,
        rig: RigConfig,
        *,
        out_dir: Path,
        access: RigAccess | None = None,
        confirm_mode: ConfirmMode = ConfirmMode.PROMPT,
        operator: str = "",
    ):
        if confirm_mode not in tuple(ConfirmMode):
            raise ValueError(f"confirm_mode {confirm_mode!r} is not one of prompt, remote, auto")
        self.rig = rig
        self.out_dir = Path(out_dir)
        self.access = access or RigAccess.of_rig(rig)
        self.confirm_mode = ConfirmMode(confirm_mode)
        self.run_id: str | None = None
        self.operator = operator  # who starts the next run (orbitrig.run.provenance)
        self.console_user: str | None = None  # who sends a request that names nobody (a terminal's user)
        self.timing: dict[str, float] = {}  # wall s per activity (bench)
        self._subs: list[Subscriber] = []
        self.revolution_taps: list[Callable[[Revolution], None]] = []  # every revolution (orbitrig.service.live)
        self._control = RunControl(self._state_changed, self._note, self._own_stop)
        self._store: RunStore | None = None
        self._io: RigIO | None = None
        self._body: asyncio.Task[Outcome] | None = None
        self._failure: Trip | None = None
        self._t0 = self._log_t0 = time.monotonic()
        self._progress = ProgressMeter(self._emit, self.access.time_scale)
        self._background = Background(self.timing, self._background_failed)
        self._held: list[Callable[[], None]] | None = None  # disk writes held while stop words go out

    # ------------------------------------------------------------- public API
    @property
    def state(self) -> RunState:
        return self._control.state

    @property
    def message(self) -> str:
        return self._control.message

    @property
    def since(self) -> str:
        return self._control.since

    @property
    def waiting_step(self) -> str | None:
        return self._control.waiting_step

    @property
    def io(self) -> RigIO | None:
        """The open rig while a run has it, else None."""
        return self._io

    def subscribe(self, callback: Subscriber) -> None:
        self._subs.append(callback)

    # ------------------------------------------------------------------- run
    async def run(
        self, plan: Plan | MatrixConfig, *, resume: bool = False, store: RunStore | None = None
    ) -> RunOutcome:
        """Run `plan` (a matrix is made into a plan first: ConfigError before anything moves);
        ``store``: the run a resume continues, opened already by the caller (else opened here)."""
        if self.state not in (IDLE, FAULTED):
            raise OrbitrigError(f"a run is active (state {self.state})")
        plan = plan if isinstance(plan, Plan) else make_plan(plan, self.rig)
        store, done = open_store(plan, self.rig, self.access, self.operator, self.out_dir, resume, store)
        self._store, self._failure, self._let_go, self._end_written = store, None, False, False
        store.warned = store_notes.on_loop(asyncio.get_running_loop(), self._emit, store.run_id)
        self.run_id, self._opening = store.run_id, None  # the stored run's id: the catalog's, a resume's too
        self._control.reset()
        io = RigIO(self.rig, self.access.endpoints, on_revolution=self._on_revolution)
        status, message = FAILED, "run cancelled"
        with pymodbus_into(store):
            try:  # every way out from here on records the run's end (store.run_id said "running")
                plan = _started_order(plan, store) if resume else plan
                self._start(plan, store, done, resume)
                status, message = await self._operate(io, store, plan, set(done))
            except asyncio.CancelledError:
                status, message = ABORTED, "run cancelled"
                raise
            except Exception as err:  # noqa: BLE001 - _start's, the resume's order: nothing opened yet
                status, message = self._not_started(err)
            finally:
                status, message = await self._make_safe(io, store, status, message)
                store.release()  # another process may resume it from here on
        return RunOutcome(status, message, store.run_id, self.out_dir, completed_points(store), len(plan.points))

    def _not_started(self, err: Exception) -> tuple[Outcome, str]:
        """A run that failed before it opened the rig (its start's free-space check, a bug): (failed,
        its cause), its state made running first if its start was not reached (`_make_safe` ends it)."""
        log.error("run failed as it started", exc_info=err)
        message = f"storage failed: {err}" if isinstance(err, StorageError) else f"{type(err).__name__}: {err}"
        if self._control.state in (IDLE, FAULTED):
            self._control.fire("start", f"run {self.run_id} could not start: {message}")
        return FAILED, message

    def _start(self, plan: Plan, store: RunStore, done: list[int], resume: bool) -> None:
        self._t0 = time.monotonic()
        self._log_t0 = self._t0 - (run_age(store) if resume else 0.0)  # the logs' t: s since the run started
        self.timing.clear()
        self.timing.update(wall=0.0, settle=0.0, acquire=0.0, confirm=0.0, suspended=0.0)
        self._control.timing = self.timing
        self._background = Background(self.timing, self._background_failed)
        self._planned = MappingProxyType(plan.blocks())
        todo = [p for p in plan.points if p.index not in done]
        kept = {p.index for p in todo}
        remaining = sum(
            PointProcedure.estimate_of(s, self.confirm_mode) for s in plan.steps if s.point is None or s.point in kept
        )
        self._progress.start(store.run_id, len(plan.points), remaining, before=len(plan.points) - len(todo))
        store.log(
            f"{'resume' if resume else 'start'} run {self.run_id}: matrix {plan.name}, "
            f"{len(todo)} of {len(plan.points)} points to run, sim={self.access.simulated}"
        )
        for line in resume_events(store, self.rig, self.operator) if resume else ():
            self._log_event(line)
        for line in warning_lines(plan.matrix, plan.rig.averaging.revolutions, plan.rig):  # as the dry run printed them
            self._log_event(line)
        try:
            store.check_free_space(plan_bytes(self.rig, [s for s in plan.steps if s.point is None or s.point in kept]))
        except StorageFullError as err:
            self._log_event(f"warning: the whole plan may not fit ({err}); the run pauses before a point that does not")
        self._control.fire("start", f"run {self.run_id} started" + (" (resumed)" if resume else ""))
        self._command(RunCommand.START, self.operator, f"run {self.run_id}" + (", resumed" if resume else ""))

    async def _operate(self, io: RigIO, store: RunStore, plan: Plan, done: set[int]) -> tuple[Outcome, str]:
        """Open the rig and execute the plan: (status, message)."""
        try:
            self._opening = opening = asyncio.ensure_future(io.__aenter__())  # an abort lets go of it at once
            try:
                await opening
            except Exception as err:
                raise RunFailed(f"cannot open the rig: {type(err).__name__}: {err}") from err
            self._io = io
            procedure = self._procedure(io, store)
            status = await self._watched(self._execute(plan, done, procedure), procedure.r)
            return status, ALL_COMPLETED if status == COMPLETED else stopped(self._control)
        except asyncio.CancelledError:
            if self._failure is not None:
                return FAILED, f"interlock: {self._failure.message}"
            if (failed := self._background.failure_message()) is not None:
                return FAILED, failed
            if self._control.abort_requested and not _cancelling():
                return ABORTED, aborted(self._control)
            if self._control.stop_now is not None and not _cancelling():
                return STOPPED, stopped(self._control)
            raise
        except (OrbitrigError, OSError) as err:  # an OSError from elsewhere (a device, a socket) is no storage failure
            if self._failure is not None:  # the interlock that ended the run (`_watched`): its cause
                return FAILED, f"interlock: {self._failure.message}"
            if isinstance(err, StorageError):
                message = f"storage failed: {err}"
            else:
                message = str(err) if isinstance(err, OrbitrigError) else f"{type(err).__name__}: {err}"
            log.error("run failed: %s", message)
            return FAILED, message
        except Exception as err:  # a bug: the drives still stop and the file is closed
            log.exception("run failed")
            return FAILED, f"{type(err).__name__}: {err}"

    async def _watched(self, body, parts: RunParts) -> Outcome:
        """Run `body` beside the interlock supervisor and the log monitor."""
        supervisor = parts.supervisor
        supervisor.sample()
        helpers = [
            asyncio.create_task(supervisor.watch(), name="interlocks"),
            asyncio.create_task(monitor(parts.store, lambda: self._io, self._log_t0), name="run-monitor"),
        ]
        for task in helpers:  # one that raises ends the run at once (not only when the body ends)
            task.add_done_callback(self._helper_ended)
        self._body = asyncio.create_task(body, name="run-body")
        if self._failure is not None or self._control.abort_requested or self._control.stop_now:  # while opening
            self._body.cancel()
        try:
            return await self._body
        except OrbitrigError:  # failed on what an interlock finds (a drive stopped elsewhere): said as that
            supervisor.look()
            raise
        finally:
            self._body = None
            for task in helpers:
                task.cancel()
            await asyncio.gather(*helpers, return_exceptions=True)

    def _procedure(self, io: RigIO, store: RunStore) -> PointProcedure:
        supervisor = InterlockSupervisor(
            lambda: (io.open_aux.latest(), io.drives_judged()), self.rig.interlocks, self._interlock_failed
        )
        return PointProcedure(
            RunParts(
                self.rig,
                self.access,
                io,
                store,
                self._control,
                supervisor,
                self._background,
                self._progress,
                self.timing,
                self.confirm_mode,
                store.run_id,
                self._emit,
                self._note,
            )
        )

    async def _execute(self, plan: Plan, done: set[int], procedure: PointProcedure) -> Outcome:
        control, first = self._control, True
        procedure.last_safe = last_safe_point(s for s in plan.steps if s.point is None or s.point not in done)
        try:
            for p in plan.points:
                if p.index in done:
                    continue
                meter, named = self._progress, f"{p.label} (point {point_name(p.index)})"
                of = f"{meter.points}" + (f" ({meter.before} measured before the resume)" if meter.before else "")
                control.between_points(p.label, f"next: point {meter.point + 1} of {of}: {named}")
                await control.safe_point()
                await control.hold_for_room(functools.partial(no_room, procedure.r.store, self.rig, plan, p))
                meter.next_point(len(p.blocks), p.label)
                control.now_doing(f"measuring point {meter.point} of {of}: {named}")
                await procedure.run_point(p, plan.point_steps(p.index), first)
                first = False
            if plan.final_steps:
                self._progress.label = None  # no point under way in the statuses
                control.closing_ramp()
            for step in plan.final_steps:
                await procedure.run_step(step, None)
        except StopRun:  # the drives stop first; the storage in flight is settled after (_make_safe)
            return STOPPED
        return STOPPED if control.stop_requested else COMPLETED


def _cancelling() -> bool:
    """Is the current task itself being cancelled (not only a task it awaited)?"""
    task = asyncio.current_task()
    return task is not None and task.cancelling() > 0
