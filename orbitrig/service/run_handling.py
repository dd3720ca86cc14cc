"""The run of the rig service (a mixin of :class:`orbitrig.service.rig_service.RigService`):
``start`` makes the executor and runs it in a task of the service; its events become the
``status``, ``result``, ``progress`` and ``note`` (its warnings) messages (docs/protocols/mqtt.md; every
status of the run names its latest progress), the live feed and the report's figures follow it, and
its end is the one closing ``idle`` status with the run's grouped warnings. Stopping it is the
command side's (orbitrig.service.commands)."""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import threading
from types import MappingProxyType
from collections.abc import Callable, Mapping
from typing import Any

from orbitrig.analysis.report_ahead import FiguresAhead
from orbitrig.analysis.run_warnings import closing_warnings, result_fit_warnings
from orbitrig.analysis.warning_groups import warning_lines
from orbitrig.catalog.errors import shown_url
from orbitrig.errors import ConfigError, OrbitrigError
from orbitrig.run.engine import Event, NoteEvent, ProgressEvent, ResultEvent, Severity, StatusEvent
from orbitrig.run.heap import trim_heap
from orbitrig.run.ending import closing_why
from orbitrig.run.states import RunState
from orbitrig.service import live as live_feed
from orbitrig.service import protocol as proto
from orbitrig.service.catalog_feed import FINISH_S, CatalogFeed
from orbitrig.service.commands import SHUTTING_DOWN, CommandHandling, Later
from orbitrig.service.engine_port import Engine, EngineFactory, MatrixLoader, RigCheck
from orbitrig.service.idle_stop import Outcome
from orbitrig.service.note_budget import WINDOW_S, NoteBudget
from orbitrig.service.settings import CommandRefused, ServiceSettings

log = logging.getLogger("orbitrig.service.rig_service")

#: seconds a shutdown waits for a start's rig check under way (each transport is asked within 2 s)
CHECK_WAIT_S = 5.0

#: said of a run the service cut short: its cleanup's wait for the drives' standstill was cancelled
NOT_CONFIRMED = "drives' stop not confirmed (see run.log)"


def stop_after_cancel(engine: Engine) -> str:
    """How the closing stop of a run cancelled in it ended (it goes on through the cancellation,
    orbitrig.run.safe_stop): 'standstill confirmed (see run.log)', or NOT_CONFIRMED."""
    return "standstill confirmed (see run.log)" if engine.standstill_confirmed else NOT_CONFIRMED


def _drop_unused_folder(engine: Engine) -> None:
    """The run's folder (store.identity.claim_dir), claimed new for a run that never began: removed
    if nothing was written in it (its empty folders, e.g. a store's ``points/`` made before the
    run id could be taken, go with it; any file is left, and the folders holding it)."""
    folders = [p for p in engine.out_dir.rglob("*") if p.is_dir() and not p.is_symlink()]
    for folder in [*sorted(folders, key=lambda p: len(p.parts), reverse=True), engine.out_dir]:
        with contextlib.suppress(OSError):
            folder.rmdir()


class RunHandling(CommandHandling):
    """The run side of the rig service (the attributes below are the service's)."""

    settings: ServiceSettings
    _engine_factory: EngineFactory
    _load_matrix: MatrixLoader
    _rig_check: RigCheck | None
    _catalog: CatalogFeed | None
    _live: live_feed.LiveFeed | None
    _ahead: FiguresAhead | None
    #: the service's wait ran out and cancelled the run before its drives' closing stop had ended
    _cut_short: bool
    #: FitWarnings of the run's completed points (grouped in each result)
    _fit_warnings: list
    #: the run's warnings published on <prefix>/note (at most note_budget.BURST a minute)
    _notes: NoteBudget
    #: what the statuses of the run started last (``_engine``) name besides: its matrix, who started it, its folder
    _run_named: Mapping[str, str] = MappingProxyType({})
    #: the latest progress of the run started last (None: none yet), named by its statuses until it ends
    _progress: ProgressEvent | None = None
    #: the status said last, as status_payload takes it (its ``since`` as said): made again with each progress
    _said: Mapping[str, Any] = MappingProxyType({})
    _loop: asyncio.AbstractEventLoop | None
    _thread: int
    _run_end_timeout: Callable[[], float]
    _send: Callable[..., None]

    async def _run(self, engine: Engine, name: str, matrix: Any) -> None:
        log.info("run of matrix %r starting", name)
        self.request_failed = None
        try:
            outcome = await engine.run(matrix)
        except asyncio.CancelledError:
            self._close_figures()  # here, at once: the service is shutting down
            failed = "" if self.request_failed is None else f" (its {self._failed_words(self.request_failed)})"
            why = f"run of {name!r} cancelled{failed}; its drives' closing stop: {stop_after_cancel(engine)}"
            self._set_status(RunState.IDLE, self._run_id, why, extra=self._close_notes())
            raise
        except Exception as err:  # reported, the service goes on
            await asyncio.to_thread(self._close_figures)
            log.exception("run of matrix %r failed", name)
            counts = self._close_notes()
            if self._state != RunState.FAULTED:
                self._set_status(RunState.FAULTED, self._run_id, f"run of {name!r} failed: {err}", extra=counts)
            else:
                self._counted_again(counts)
            return
        try:
            await self._closing_status(name, outcome)
        except Exception as err:  # the run has ended (drives stopped, recorded): the service goes on
            log.exception("run %s of matrix %r: its closing summary failed", self._run_id, name)
            if self._state not in proto.ENDED:
                self._set_status(
                    RunState.IDLE, self._run_id, f"run {outcome.status}; its closing summary failed: {err}"
                )

    async def _closing_status(self, name: str, outcome: Any) -> None:
        """The run's only idle status, with its grouped warnings (read from the stored run)."""
        await asyncio.to_thread(self._close_figures)  # the point it was drawing is left to the report
        status = outcome.status
        log.info("run %s of matrix %r ended: %s: %s", self._run_id, name, status, outcome.message)
        summary = await asyncio.to_thread(closing_warnings, outcome.out_dir)
        trim_heap()  # what the run freed goes back to the system before the next run
        seconds, engine = self._run_end_timeout(), self._engine
        stop = NOT_CONFIRMED if engine is None else stop_after_cancel(engine)
        cut = (
            f"; cancelled after {seconds:.0f} s, its drives' closing stop not ended; that stop: {stop}"
            if self._cut_short
            else ""
        )
        counts = self._close_notes()  # ahead of the status that ends the run
        if self._state not in proto.ENDED:
            warnings = "".join(f"{proto.GROUPED_WARNING}{w}" for w in summary)
            why = closing_why(status, outcome.message)  # who stopped it, and why (orbitrig.run.ending)
            self._set_status(RunState.IDLE, self._run_id, f"run {status}{why}{cut}{warnings}", extra=counts)
        else:
            self._counted_again(counts)

    async def _catalog_finished(self) -> None:
        """The catalog's adds in flight finished before the service leaves, for at most
        catalog_feed.FINISH_S (a database that does not answer): those left are named."""
        if self._catalog is None:
            return
        left = await asyncio.to_thread(self._catalog.finish, FINISH_S)
        if left:
            log.warning(
                "catalog %s did not answer within %.0f s: not added: %s (`orbitrig catalog add` adds them later)",
                shown_url(self._catalog.url),
                FINISH_S,
                " ".join(str(run_dir) for run_dir in left),
            )

    def _close_figures(self) -> None:
        ahead, self._ahead = self._ahead, None
        if ahead is not None:
            ahead.close()
            log.info(
                "report figures: %d point(s) handed to the drawing process, %d not (`orbitrig report` draws "
                "what it did not finish)",
                len(ahead.handed),
                len(ahead.dropped),
            )

    def _cmd_start(self, cmd: proto.Command) -> Later | None:
        """The matrix loaded and checked, then (given a rig check) the rig's transports asked off the
        loop before the run folder is made: the reply follows that check (a Later)."""
        if self.run_active:
            raise CommandRefused(
                f"a run is active (run {self._run_id}, state {self._state}): stop or abort it before starting another"
            )
        if self._start_checked is not None:
            raise CommandRefused("a start is under way (the rig's transports are being asked): wait for its reply")
        matrix_name, folder = cmd.matrix, self.settings.matrices_dir
        if matrix_name is None:  # (the protocol's model requires it: a command built elsewhere)
            raise CommandRefused("start needs the field 'matrix'")
        path = folder / f"{matrix_name}.toml"
        if not path.is_file():
            names = sorted(p.stem for p in folder.glob("*.toml")) if folder.is_dir() else []
            raise CommandRefused(
                f"no matrix {matrix_name!r} in the matrix folder (available: {', '.join(names) or 'none'})"
            )
        try:
            matrix = self._load_matrix(path)
        except ConfigError as err:
            problems = "; ".join(err.problems)
            raise CommandRefused(f"matrix {matrix_name!r} is invalid: {problems} (file {err.file})") from err
        if self._rig_check is None:
            self._begin(cmd, matrix_name, matrix)
            return None
        self._start_called_off = None
        assert self._tg is not None
        task = self._tg.create_task(self._checked_start(cmd, matrix_name, matrix), name=f"rig-check-{matrix_name}")
        self._start_checked = task
        return task

    async def _checked_start(self, cmd: proto.Command, name: str, matrix: Any) -> Outcome:
        """The start's reply (error, detail) once the rig's transports have answered (each opened once,
        nothing written to the drives, in a thread of its own: the loop keeps serving) and the run has
        begun; refused in the rig check's words (orbitrig.run.rig_answers) when one does not answer,
        no run folder made, the service ready for the next start."""
        assert self._rig_check is not None
        try:
            await asyncio.to_thread(asyncio.run, self._rig_check())
        except OrbitrigError as err:
            log.warning("start of matrix %r refused: %s", name, err)
            return f"start of {name!r} refused: {err}", None
        except Exception as err:  # the check itself failed: nothing started, the service goes on
            log.exception("start of matrix %r: the rig check failed", name)
            return f"start of {name!r} refused: the rig's transports could not be asked: {err!r}", None
        finally:
            self._start_checked = None
        if self.closing:
            return SHUTTING_DOWN.format(cmd=cmd.cmd), None
        if self._start_called_off is not None:
            what = self._start_called_off
            return f"start of {name!r} withdrawn: {what} came while the rig was asked (nothing started)", None
        try:
            self._begin(cmd, name, matrix)
        except CommandRefused as refusal:
            return refusal.reason, None
        except Exception as err:  # as _carry_out words a handler's failure
            log.exception("command start failed")
            return f"{cmd.cmd} failed: {err}", None
        return None, None

    async def _start_check_over(self) -> None:
        """At shutdown: a start's rig check under way is waited for (at most CHECK_WAIT_S; then
        cancelled), so that its thread has closed its links and the start's refusal is sent."""
        task = self._start_checked
        if task is not None and not (await asyncio.wait([task], timeout=CHECK_WAIT_S))[0]:
            log.warning("a start's rig check did not end within %.0f s of the shutdown: cancelled", CHECK_WAIT_S)
            task.cancel()

    def _begin(self, cmd: proto.Command, matrix_name: str, matrix: Any) -> None:
        """The run's executor made (its folder claimed) and its task started."""
        engine = self._engine_factory(matrix_name, matrix)
        engine.operator = cmd.by or ""  # recorded in the run with every command's sender
        # the live feed before the run task: if it cannot be attached, the start fails and nothing moves
        try:
            live = live_feed.attach(engine, matrix, lambda p: self._send(self.topics.live, p, proto.QOS_LIVE))
        except Exception:
            _drop_unused_folder(engine)
            raise
        engine.subscribe(self._on_event)
        if self.settings.draw_figures:  # at the lowest CPU priority; `orbitrig report` reuses them
            self._ahead = FiguresAhead(engine.out_dir)
            engine.subscribe(self._ahead.on_event)
        self._engine, self._live, self._cut_short, self._progress = engine, live, False, None
        self._run_id, self._fit_warnings, self._notes = engine.run_id, [], NoteBudget()
        self._run_named = {
            "matrix": matrix_name,
            **({"by": cmd.by} if cmd.by else {}),
            "folder": str(engine.out_dir.resolve()),  # where `orbitrig sweep --resume` takes it up, say
        }
        assert self._tg is not None
        self._run_task = self._tg.create_task(self._run(engine, matrix_name, matrix), name=f"run-{matrix_name}")
        self._run_task.add_done_callback(lambda task: self._run_task_ended(task, engine))
        if live is not None:
            self._tg.create_task(live.run(self._run_task), name=f"live-{matrix_name}")

    def _run_task_ended(self, task: asyncio.Task[None], engine: Engine) -> None:
        """The run's task has ended: the catalog adds the run's final status and end, whatever its
        outcome; a run that never began (the engine took no run id: a shutdown or an abort that
        came with its start cancelled it, or its store could not be opened) leaves no run: its
        folder goes if nothing was written in it."""
        if engine.run_id is None:
            _drop_unused_folder(engine)
        elif self._catalog is not None:
            self._catalog.run_ended(engine.out_dir)

    # -- executor events --------------------------------------------------------

    def _on_event(self, event: Event) -> None:
        """Executor event -> MQTT message (thread-safe: sent from the service's loop)."""
        if isinstance(event, NoteEvent):
            if event.severity is Severity.WARNING:  # routine notes stay in run.log
                self._on_loop(self._publish_warning, event, proto.iso8601())  # stamped when said
            return
        self._on_loop(self._publish_event, event)

    def _publish_event(self, event: Event) -> None:
        """A status, result or progress event as its MQTT message (on the service's loop)."""
        if isinstance(event, StatusEvent):
            if event.state == RunState.IDLE and self.run_active:
                return  # the run's closing idle status (with its grouped warnings) follows from _run
            extra = (self._live.waiting_fields(event.state) if self._live is not None else None) or {}
            if event.point_label is not None:  # the operating point under way, or the next one (an extension)
                extra = {
                    "point_label": event.point_label,
                    **({"between_points": True} if event.between_points else {}),
                    **extra,
                }
            self._set_status(event.state, event.run_id, event.message or "", event.since, extra)
        elif isinstance(event, ResultEvent):
            self._fit_warnings += result_fit_warnings(event.payload)  # the run's warnings so far, grouped
            payload = {**event.payload, "warning_groups": warning_lines(self._fit_warnings)}
            self._send(self.topics.result, proto.result_payload(event.run_id, payload), proto.QOS_RESULT)
            if self._catalog is not None and self._engine is not None:
                self._catalog.point_completed(self._engine.out_dir, event.payload["point"])
        elif isinstance(event, ProgressEvent):
            self._send(self.topics.progress, proto.progress_payload(event), proto.QOS_PROGRESS)
            if self.run_active and event.run_id == self._run_id:
                self._progress = event
                if self._said.get("run_id") == event.run_id:  # the status sent again (reconnection, `status`) names it
                    self._status = self._status_now()
        else:
            log.debug("ignored event %r", event)

    def _on_loop(self, call: Callable[..., None], *args: Any) -> None:
        """``call(*args)`` on the service's event loop (at once when already on it)."""
        if threading.get_ident() != self._thread and self._loop is not None:
            self._loop.call_soon_threadsafe(call, *args)
        else:
            call(*args)

    def _publish_warning(self, event: NoteEvent, at: str) -> None:
        """One warning of the run on ``<prefix>/note`` (retained: the latest for a late subscriber),
        within the run's NoteBudget. One that reaches the loop after its run's closing note (said late
        from another thread), or once another run has begun, is not published: the closing note stays
        the run's last word and the next run's budget its own (run.log has it)."""
        if self._notes.closed or event.run_id != self._run_id:
            log.info("run %s: a warning said after its run's end, not published: %s", event.run_id, event.message)
            return
        withheld = self._notes.admit(event.kind)
        if withheld is None:
            if self._notes.withheld == 1:
                log.warning(
                    "run %s: over %d warnings in %.0f s: not all published (run.log has them)",
                    event.run_id,
                    self._notes.burst,
                    WINDOW_S,
                )
            return
        notes = self._notes
        payload = proto.note_payload(
            event.run_id, event.severity, event.message, at, withheld, notes.released_kinds, notes.said
        )
        self._send(self.topics.note, payload, proto.QOS_NOTE, True)

    def _close_notes(self) -> dict[str, Any]:
        """The run's warnings at its end: those still withheld said by one closing note (over the
        budget: it is the last); the run's counts returned for its closing status (``"notes"``)."""
        notes = self._notes
        notes.closed = True  # its last word: a warning said later is not published
        withheld, kinds = notes.take_withheld()
        if withheld:
            told = ", ".join(f"{kind} {n}" for kind, n in kinds.items())
            many = "1 warning" if withheld == 1 else f"{withheld} warnings"
            message = (
                f"the run ended with {many} not published here (at most {notes.burst} "
                f"in {notes.window_s:.0f} s): {told}; run.log has them"
            )
            payload = proto.note_payload(
                self._run_id, Severity.WARNING, message, proto.iso8601(), withheld, kinds, notes.said, closing=True
            )
            self._send(self.topics.note, payload, proto.QOS_NOTE, True)
        return {"notes": notes.totals()}

    def _counted_again(self, counts: dict[str, Any]) -> None:
        """The run's end said already by the engine (``faulted``): that status once more, the same
        but for the run's counts of warnings (``counts``), so that the run's final status has them."""
        last = json.loads(self._status)
        if last.get("run_id") != self._run_id or "notes" in last:
            return
        extra = {k: v for k, v in last.items() if k not in ("state", "run_id", "since", "message")}
        state = RunState(last["state"])  # the word read back: the enum the service keeps
        self._set_status(state, self._run_id, last["message"], last["since"], {**extra, **counts})

    def _set_status(
        self,
        state: proto.StatusState,
        run_id: str | None,
        message: str | None,
        since: Any = None,
        extra: dict[str, Any] | None = None,
    ) -> None:
        self._state, self._run_id = state, run_id
        ours = run_id is not None and self._engine is not None and run_id == self._engine.run_id
        extra = {**self._run_named, **(extra or {})} if ours else extra  # every status of the run: what, for whom
        said = {"state": state, "run_id": run_id, "since": proto.iso8601(since), "message": message, "extra": extra}
        self._said = MappingProxyType(said)
        self._status = self._status_now()
        self._send(self.topics.status, self._status, proto.QOS_STATUS, True)

    def _status_now(self) -> bytes:
        """The status said last, naming the latest progress of its run while the run goes on (a subscriber
        that comes later, while the run waits for the operator or is paused, learns where it is)."""
        state, run_id, latest = self._said.get("state"), self._said.get("run_id"), self._progress
        under_way = state not in proto.ENDED and state != proto.OFFLINE
        ours = under_way and latest is not None and run_id is not None and latest.run_id == run_id
        return proto.status_payload(**self._said, progress=latest if ours else None)
