"""The rig service's commands: each one validated, carried out and answered once
(docs/protocols/mqtt.md, "Commands"); a handler refuses by raising
:class:`CommandRefused`, which :meth:`CommandHandling.handle_command` turns into
the ``ok: false`` reply. ``stop`` and ``abort`` are always accepted; an abort that no run
carries out (none holds the drives) sends both drives the emergency stop (a stop: the ramp stop)
over a link of the service's own and is answered once that is done
(orbitrig.service.drive_stops)."""

from __future__ import annotations

import asyncio
import collections
import functools
import logging
import time
from collections.abc import Callable
from enum import StrEnum

from orbitrig.errors import OrbitrigError
from orbitrig.run.control import NotNow
from orbitrig.run.states import RunCommand
from orbitrig.run.states import RunState
from orbitrig.service import idle_stop
from orbitrig.service import protocol as proto
from orbitrig.service.command_json import unreadable
from orbitrig.service.drive_stops import DriveStopping
from orbitrig.service.engine_port import Engine
from orbitrig.service.link import BrokerLink
from orbitrig.service.settings import CommandRefused

log = logging.getLogger("orbitrig.service.rig_service")

#: s after a reconnection within which a command like one handled before it is logged as sent again
REDELIVERY_S = 10.0
#: stops and aborts remembered so that a retained one is carried out once only
STOPS_KEPT = 4096
#: the commands that start or move the drives: refused once the service is shutting down
MOVES_DRIVES = frozenset({RunCommand.START, RunCommand.RESUME, RunCommand.CONFIRM})
SHUTTING_DOWN = "the service is shutting down: {cmd} refused (nothing is started or moved any more)"
STOPPING_DRIVES = (
    "{cmd} refused: an abort's emergency stop is being sent to the drives (no run held them); "
    "try again once it is answered"
)
#: a handler's reply that follows once the work it started is done: (error, detail)
Later = asyncio.Future[idle_stop.Outcome]


class Request(StrEnum):
    """What the service asks of its run (:meth:`CommandHandling._request`): a command's pause, stop
    or abort (their words), or the stop at once of the service's own shutdown."""

    PAUSE = RunCommand.PAUSE.value
    STOP = RunCommand.STOP.value
    ABORT = RunCommand.ABORT.value
    STOP_NOW = "stop_now"


class CommandHandling(DriveStopping):
    """The command side of :class:`orbitrig.service.rig_service.RigService` (a mixin:
    the attributes below are the service's); the stops no run carries out: DriveStopping."""

    topics: proto.Topics
    link: BrokerLink
    _run_id: str | None
    _state: proto.StatusState
    _status: bytes
    #: (id, bytes) of recent commands -> number of the connection they came on
    _handled: collections.OrderedDict[tuple[str, bytes], int]
    #: (id, bytes) of the stops and aborts carried out in this service's life (the last STOPS_KEPT)
    _stops_done: collections.OrderedDict[tuple[str | None, bytes], None]
    #: command name -> handler (raises CommandRefused to refuse; returns a Later: its reply follows;
    #: or the reply's detail: what the command does, e.g. when a pause takes effect)
    _handlers: dict[proto.CommandName, Callable[[proto.Command], Later | str | None]]
    #: set once the service is shutting down: MOVES_DRIVES are refused from then on
    closing: bool = False
    #: what asked the service to shut down, for the run's end message (the CLI: the signal)
    shutdown_cause: str = ""
    #: the run's stop or abort that raised (its type and text): the run was cancelled for it
    request_failed: str | None = None
    #: the stop or abort that came during that check: the start is withdrawn (None: none came)
    _start_called_off: RunCommand | None = None

    def handle_command(self, payload: bytes, *, retained: bool = False) -> None:
        """Validate and execute one command; publish exactly one reply.

        A retained command (``<prefix>/cmd`` is not retained) is stale: the broker
        hands it to every new subscription, so executing it would, e.g., start a run at
        each reconnection. It is refused (one reply) and changes nothing, except a ``stop`` or
        ``abort``, which the contract has always accepted: it is carried out (stopping is the
        safe side, even of a stale request) and logged, once in the service's life (the broker
        hands it over again at each reconnection: dropped then). The broker's redelivery of an
        ordinary command taken in before the link dropped (QoS 1, its acknowledgement lost) never
        gets here: the link recognises it (DUP, packet id) and drops it, so it is executed and
        answered once; a ``stop`` or ``abort`` is carried out and answered again (repeating one does
        no harm). The same id and bytes sent again by a client are a new command: carried out and
        answered like any other, also right after a reconnection (``_note_repeat``)."""
        try:
            cmd = proto.parse_command(payload)
        except proto.CommandError as err:
            log.info("refused command %r: %s", payload[:200], err.reason)
            self._reply(err.id, err.reason, behind=True)
            return
        except Exception as err:  # no payload may kill the service
            log.exception("refused command %r: the parser failed", payload[:200])
            self._reply(None, unreadable(err), behind=True)
            return
        if cmd.cmd not in proto.ALWAYS_ACCEPTED:
            self._note_repeat(cmd, payload)
        if retained and cmd.cmd in proto.ALWAYS_ACCEPTED:  # the contract: always accepted, carried out
            if (cmd.id, bytes(payload)) in self._stops_done:  # at each reconnection: not once more
                log.warning("dropped retained %s (id %r): carried out once already", cmd.cmd, cmd.id)
                return
            log.warning("retained %s (id %r) carried out: clear it with an empty retained message", cmd.cmd, cmd.id)
        elif retained:
            log.warning("refused retained command %s (id %r)", cmd.cmd, cmd.id)
            self._reply(
                cmd.id,
                f"retained command {cmd.cmd.value!r} refused: publish commands without the "
                "retain flag (a retained command is replayed on every reconnection); "
                "clear it with an empty retained message",
            )
            return
        self._carry_out(cmd, payload)

    def _carry_out(self, cmd: proto.Command, payload: bytes) -> None:
        """Execute a command handle_command has let through and answer it (a Later: once done)."""
        t0 = time.monotonic()
        log.info("command %s (id %r)", cmd.cmd, cmd.id)
        if cmd.ignored:
            log.warning("%s accepted despite: %s", cmd.cmd, "; ".join(cmd.ignored))
        error, later, detail = None, None, None
        try:
            if self.closing and cmd.cmd in MOVES_DRIVES:
                raise CommandRefused(SHUTTING_DOWN.format(cmd=cmd.cmd))
            if cmd.cmd in MOVES_DRIVES and self.idle_stops():
                raise CommandRefused(STOPPING_DRIVES.format(cmd=cmd.cmd))
            done = self._handlers[cmd.cmd](cmd)
            later, detail = (None, done) if isinstance(done, str) else (done, None)
        except CommandRefused as refusal:
            error = refusal.reason
        except Exception as err:  # a command must never kill the service
            log.exception("command %s failed", cmd.cmd)
            error = f"{cmd.cmd} failed: {err}"
        if cmd.cmd is RunCommand.ABORT:
            log.info("abort requested of the executor %.1f ms after the message arrived", (time.monotonic() - t0) * 1e3)
        if cmd.cmd in proto.ALWAYS_ACCEPTED:
            self._stops_done[(cmd.id, bytes(payload))] = None
            if len(self._stops_done) > STOPS_KEPT:
                self._stops_done.popitem(last=False)
        if later is not None and error is None:
            later.add_done_callback(functools.partial(self._reply_when_done, cmd, cmd.id_note))
            return
        error, detail = _noted(cmd.id_note, error, detail if error is None else None)
        self._reply(cmd.id, error, detail=detail, behind=cmd.cmd not in proto.ALWAYS_ACCEPTED)

    def _note_repeat(self, cmd: proto.Command, payload: bytes) -> None:
        """Log a command with the id and bytes of one handled during an earlier connection,
        arriving within REDELIVERY_S of this one: a client sent it again (the broker's redelivery
        is dropped by the link before it gets here); it is carried out and answered as any
        other. Not asked of a stop or an abort (carried out each time anyway)."""
        if cmd.id is None:
            return
        key = (cmd.id, bytes(payload))
        earlier = self._handled.get(key)
        now, link = time.monotonic(), self.link
        if earlier is not None and earlier < link.connections and now - link.connected_at < REDELIVERY_S:
            log.info(
                "command %s (id %r) is the same as one handled before the reconnection: sent again, carried out again",
                cmd.cmd,
                cmd.id,
            )
        self._handled[key] = link.connections
        self._handled.move_to_end(key)
        if len(self._handled) > 256:
            self._handled.popitem(last=False)

    def _on_message(self, payload: bytes, retained: bool) -> None:
        """Every message on ``<prefix>/cmd``; nothing a message does may end the service."""
        try:
            self.handle_command(payload, retained=retained)
        except Exception as err:  # last line of defence; handle_command replies itself
            log.exception("command %r could not be handled", payload[:200])
            self._reply(None, f"command could not be handled: {type(err).__name__}")

    def _reply(self, cid: str | None, error: str | None, *, behind: bool = False, detail: str | None = None) -> None:
        """One reply; ``behind``: to an ordinary command (sent after statuses and results);
        ``detail``: what an ok command did, when the reply says it (an abort no run carried out)."""
        payload = proto.reply_ok(cid, detail) if error is None else proto.reply_error(cid, error)
        self.link.send(self.topics.reply, payload, proto.QOS_REPLY, behind=behind)

    def _reply_when_done(self, cmd: proto.Command, note: str | None, later: Later) -> None:
        """The reply of `cmd` once its Later is done; cancelled (the service ending): a start's says
        nothing was started (its rig check cut off), a stop's or abort's that the stop may not be sent."""
        if later.cancelled() and cmd.cmd is RunCommand.START:
            outcome: idle_stop.Outcome = (f"start of {cmd.matrix!r} not begun: cancelled (nothing started)", None)
        elif later.cancelled():
            outcome = (f"the drives' stop not confirmed sent: cancelled; {idle_stop.ESTOP}", None)
        else:
            outcome = later.result()  # (the task catches every failure: idle_stop.Outcome)
        error, detail = _noted(note, *outcome)
        self._reply(cmd.id, error, detail=detail)

    def _cmd_status(self, cmd: proto.Command) -> None:
        self.link.send(self.topics.status, self._status, proto.QOS_STATUS, True)

    def _cmd_pause(self, cmd: proto.Command) -> str | None:
        """Pause at the next safe point (while waiting for a manual setting: once it is confirmed);
        while paused: only during an interlock suspension (the run stays paused once it clears) or
        for disk space (it stays paused until resumed). The reply's detail says when it takes effect."""
        allowed = (RunState.RUNNING, RunState.WAITING, RunState.PAUSED)  # the run refuses an operator's pause held
        return self._control(RunCommand.PAUSE, lambda e: e.request_pause(by=cmd.by), allowed=allowed)

    def _cmd_resume(self, cmd: proto.Command) -> None:
        """Resume a paused run, or withdraw a pause requested and not yet reached (while
        running, waiting or suspended by an interlock): accepted, the state stays, the run does
        not pause. During a suspension with no pause to withdraw: refused by the run."""
        pending = self._engine is not None and self._engine.pause_pending
        allowed = (RunState.PAUSED, RunState.RUNNING, RunState.WAITING) if pending else (RunState.PAUSED,)
        self._control(RunCommand.RESUME, lambda e: e.request_resume(by=cmd.by), allowed=allowed)

    def _cmd_confirm(self, cmd: proto.Command) -> None:
        step = cmd.step
        if step is None:  # (the protocol's model requires it: a command built elsewhere)
            raise CommandRefused("confirm needs the field 'step'")
        self._control(RunCommand.CONFIRM, lambda e: e.confirm(step, by=cmd.by), allowed=None)

    def _cmd_stop(self, cmd: proto.Command) -> Later | None:
        """Always accepted. A run carries it out; else (no run holds the drives) both drives get the
        ramp stop (OFF1) over a link of the service's own and the reply follows, as an abort's."""
        self._call_off_start(RunCommand.STOP)
        return None if self._request(Request.STOP, cmd.by) else self._stopped_idle(emergency=False)

    def _cmd_abort(self, cmd: proto.Command) -> Later | None:
        """Always accepted. A run that holds the drives carries it out (their stop words go out at
        once); else both drives get the emergency stop over a link of the service's own and the
        reply follows, saying what was sent: never ok with nothing sent."""
        self._call_off_start(RunCommand.ABORT)
        return None if self._request(Request.ABORT, cmd.by) else self._stopped_idle(emergency=True)

    def _call_off_start(self, what: RunCommand) -> None:
        """A start whose rig check is under way is withdrawn by `what` (it starts nothing)."""
        if self._start_checked is not None:
            self._start_called_off = what

    def _stopped_idle(self, *, emergency: bool) -> Later:
        """The stop of a command no run carried out (`stop_idle_drives`; a run whose stop or abort
        raised, cancelled for it, said so: `request_failed`); CommandRefused if not sent."""
        failed = self.request_failed if self.run_active else None
        held = None if failed is None else f"the run holding them cancelled, its {self._failed_words(failed)}"
        sent = self.stop_idle_drives(emergency=emergency, held=held)
        if isinstance(sent, str):
            raise CommandRefused(sent)
        return sent

    def _control(
        self, what: RunCommand, call: Callable[[Engine], str | None], allowed: tuple[str, ...] | None
    ) -> str | None:
        """Ask the run `what` (`call`) in the states `allowed`; what the run says it does, if it says."""
        if not self.run_active or self._engine is None:
            raise CommandRefused(f"no run is active: nothing to {what}")
        state = self._engine.state
        if allowed is not None and state not in allowed:
            raise CommandRefused(f"cannot {what} while the run is {state}")
        try:
            return call(self._engine)
        except NotNow as err:  # the run's own words say why
            raise CommandRefused(str(err)) from err
        except (OrbitrigError, ValueError, RuntimeError) as err:
            raise CommandRefused(f"cannot {what}: {err}") from err

    def shutdown_words(self) -> str:
        """'the service shutting down' (on SIGTERM, ...): why a run stops at once at shutdown."""
        return "the service shutting down" + (f" on {self.shutdown_cause}" if self.shutdown_cause else "")

    def _request(self, what: Request, by: str | None = None) -> bool:
        """Ask the executor to pause/stop/abort; never raises. If the executor
        refuses a stop or abort, the run task is cancelled (its cleanup ramps
        both drives to zero). False if no run took it: none is active, or the run does not
        carry it to the drives (orbitrig.run.requests: nothing was sent)."""
        engine, task = self._engine, self._run_task
        if task is None or task.done() or engine is None:
            return False
        if what is not Request.PAUSE and engine.state == RunState.IDLE:
            if engine.run_id is None:
                task.cancel()  # the run task has not started yet: it never touches the drives
            return False  # (or the run has ended and the task is writing its closing summary)
        requests: dict[Request, Callable[..., object]] = {
            Request.PAUSE: engine.request_pause,
            Request.STOP: engine.request_stop,
            Request.ABORT: engine.request_abort,
            Request.STOP_NOW: lambda by: engine.request_stop_now(self.shutdown_words(), by=by),
        }
        try:
            return requests[what](by=by) is not False  # a stop or an abort says whether it reaches the drives
        except NotNow as err:  # a pause the run cannot take (past its last safe point): its own words
            log.info("%s not taken: %s", what, err)
            return False
        except Exception as err:
            log.exception("executor refused %s", what)
            if what is not Request.PAUSE:
                self.request_failed = " ".join(f"{type(err).__name__}: {err}".split())  # one line
                task.cancel()
            return False

    @staticmethod
    def _failed_words(failed: str) -> str:
        """'stop or abort failed (AttributeError: ...)': a run's request that raised, in the messages."""
        return f"stop or abort failed ({failed})"


def _noted(note: str | None, error: str | None, detail: str | None) -> tuple[str | None, str | None]:
    """(error, detail) of a reply with ``note`` (why the id sent is not echoed) added to what it says."""
    if note is None:
        return error, detail
    if error is not None:
        return f"{error}; {note}", detail
    return None, note if detail is None else f"{detail}; {note}"
