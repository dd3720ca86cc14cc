"""The operator's requests to a running engine (pause, resume, stop, abort, stop at once,
confirm), each logged with who sent it and when (run.log and run.h5's command log); a stop's
and an abort's sender is kept for the run's end message (orbitrig.run.ending).

An abort or a stop at once sends both drives their stop words first: until those are
out, the engine's run.log lines and the commands (disk writes, the command journal
fsync'd) are held and then written in their order (`_write_later`), so that no slow
disk delays the stop (nor blocks the event loop long enough to trip the drives'
comm-loss watchdog before it).
"""

from __future__ import annotations

import asyncio
import functools
import logging
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

from drives.errors import DriveError
from orbitrig.config import RigConfig
from orbitrig.run.control import RunControl
from orbitrig.run.provenance import UNNAMED
from orbitrig.run.states import RunCommand
from orbitrig.run.states import Outcome
from orbitrig.store.writer import RunStore

if TYPE_CHECKING:
    from orbitrig.run.rig_io import RigIO

log = logging.getLogger(__name__)


def requester(by: str, why: str = "") -> str:
    """The sender as the commands log records it: 'ada', 'ada (SIGHUP: the terminal was closed)'."""
    return f"{by} ({why})" if why else by


class OperatorRequests:
    """Mixin of `RunEngine`: what an operator (terminal, MQTT, dashboard) may ask of a run.
    ``by`` names the sender; without it the console user (or UNNAMED)."""

    rig: RigConfig
    console_user: str | None
    _control: RunControl
    _body: asyncio.Task[Outcome] | None
    _store: RunStore | None
    _io: RigIO | None
    _log_event: Callable[..., None]
    _held: list[Callable[[], None]] | None  # disk writes held until the stop words are out
    _holding_for: asyncio.Task[list[DriveError]] | None = None  # the stop whose delivery releases them
    _let_go = False  # the run's closing stop is over (confirmed or not): its cleanup closes the drives' link
    _opening: asyncio.Task[RigIO] | None = None  # the rig's links being opened (RigIO entered)

    def request_pause(self, by: str | None = None) -> str:
        """Pause (orbitrig.run.control); returns when it takes effect ('the run pauses once
        manual:0003 is confirmed ...'), the words the service's reply says."""
        when = self._control.request_pause(self._sender(by))
        self._command(RunCommand.PAUSE, by)
        return when

    @property
    def pause_pending(self) -> bool:
        """A pause requested and not yet reached at a safe point (a resume withdraws it)."""
        return self._control.pause_pending

    def request_resume(self, by: str | None = None) -> None:
        self._control.request_resume()
        self._command(RunCommand.RESUME, by)

    def request_stop(self, by: str | None = None, why: str = "") -> bool:
        """Stop at the next safe point; `by` (and `why`, e.g. the signal that asked) are kept for
        the commands log and the run's end message (orbitrig.run.ending). Returns whether the run
        carries the stop to the drives: False once it has let go of them (`let_go`); the caller
        then stops them another way (orbitrig.service.idle_stop), as for an abort."""
        sender = requester(self._sender(by), why)
        self._control.request_stop(sender)
        self._command(RunCommand.STOP, sender)
        return not self._let_go

    @property
    def stop_words(self) -> asyncio.Task[list[DriveError]] | None:
        """The drives' stop words of an abort (or a stop at once) still going out; None once they
        are out, or when none were sent."""
        task = self._holding_for
        return task if task is not None and not task.done() else None

    @property
    def let_go(self) -> bool:
        """The run's cleanup is past its closing stop (the drives' link closing or closed, their
        standstill confirmed or not): no stop asked of it reaches the drives any more."""
        return self._let_go

    def request_abort(self, by: str | None = None, why: str = "") -> bool:
        """Abort: both drives get the emergency stop at once (their stop words ahead of
        everything waiting for the drives' link, not after the run has unwound), then the
        run is cancelled; its cleanup repeats the stop and waits for standstill. Nothing is
        written to disk before the stop words are out (run.log, the command's durable record).
        The first abort's sender (`by`, `why`) is the one the run ends with. Every abort while
        the run is aborting cancels its body again: a cancel can be lost (Python 3.11's
        asyncio.wait_for swallows one that comes as its awaitable completes).

        Returns whether the run holds the drives: True if the stop words went out now, or an
        abort under way sent them with the rig still open (its cleanup repeats them); False if
        nothing reached the drives through the run: its rig is not open (not yet: its opening is
        then cancelled, so that the drives' link is free at once; or closed by its cleanup, also
        when that could not confirm them stopped). The caller then stops them another way
        (orbitrig.service.idle_stop), or says it could not."""
        by = requester(self._sender(by), why)
        starts = self._control.abort_starts
        if starts:
            self._control.abort_by = by
        t0 = time.monotonic()
        sending = self._stop_first(emergency=True) if starts else None
        self._control.request_abort()
        if self._control.abort_requested and self._body is not None and not self._body.done():
            self._body.cancel()  # again on a further abort: the body may have missed the first
        if self._opening is not None and not self._opening.done():  # the drives' port let go at once
            self._opening.cancel()  # (an RTU line held while a slow drive answers); they are not the run's
        if sending is None:
            self._command(RunCommand.ABORT, by)
            return not starts and self._repeat_stop()
        sending.add_done_callback(lambda task: self._stopped_now(task, t0, by))
        return True

    def _repeat_stop(self) -> bool:
        """A further abort: the emergency stop sent again while the run's drives are open (harmless
        if the first is under way); False once their link is closed (the cleanup closed it, also
        when it could not confirm them stopped): the caller stops them another way."""
        again = self._stop_drives_now(emergency=True)
        if again is None:
            return False
        again.add_done_callback(lambda task: task.cancelled() or task.exception())  # its errors: the first's
        return True

    def _stop_first(self, emergency: bool) -> asyncio.Task[list[DriveError]] | None:
        """Send both drives their stop words now and hold the disk writes until they are out."""
        sending = self._stop_drives_now(emergency)
        if sending is not None:
            self._held = [] if self._held is None else self._held
            self._holding_for = sending  # a stop queued behind another: held until the last is out
            sending.add_done_callback(self._release_held)
        return sending

    def _release_held(self, task: asyncio.Task[list[DriveError]]) -> None:
        if task is not self._holding_for or self._held is None:
            return
        held, self._held, self._holding_for = self._held, None, None
        for write in held:
            self._write_later(write)

    def _write_later(self, write: Callable[[], None]) -> None:
        """`write` (a run.log line, a command's record) now, or once the stop words are out."""
        if self._held is not None:
            self._held.append(write)
            return
        try:
            write()
        except Exception:  # best effort, as run.log is: the run goes on
            log.exception("cannot record %s", write)

    def _stop_drives_now(self, emergency: bool) -> asyncio.Task[list[DriveError]] | None:
        """The stop words' task, or None if the run cannot send them: its rig is not open (not
        yet, or closed by the cleanup, which may not have confirmed the drives stopped). A rig whose
        opening has ended is open, also before the run has resumed from it (`_opened`)."""
        io = self._opened()
        drives = io.drives if io is not None else None
        if drives is None:
            return None
        try:
            return drives.stop_now(emergency=emergency)
        except DriveError:
            return None  # closed already by the cleanup

    def _opened(self) -> RigIO | None:
        """The run's open rig: `_io`, or the result of its opening once that has ended (the run
        takes it up a step later: a stop asked in between is the run's to send, its port held)."""
        opening = self._opening
        if self._io is not None or opening is None or not opening.done() or opening.cancelled():
            return self._io
        return opening.result() if opening.exception() is None else None

    def _stopped_now(self, task: asyncio.Task[list[DriveError]], t0: float, by: str | None) -> None:
        errors = "cancelled" if task.cancelled() else task.exception() or task.result()
        self._log_event(
            f"drives: emergency stop (OFF3) sent on the abort in {(time.monotonic() - t0) * 1e3:.0f} ms"
            + (f"; not delivered: {errors}" if errors else "")
        )
        self._command(RunCommand.ABORT, by)

    def request_stop_now(self, why: str, by: str | None = None) -> None:
        """Stop at once (`why`, e.g. 'SIGTERM'): the block under way is dropped, both drives ramp
        to zero (OFF1, not an emergency), the run ends stopped and can be resumed. Their stop
        words go out first: nothing is written to disk before (run.log, the command's record)."""
        body = self._body if self._body is not None and not self._body.done() else None
        if self._control.stop_now_starts and body is not None:
            self._stop_first(emergency=False)
        if self._control.request_stop_now(why) and body is not None:
            body.cancel()
        self._command(RunCommand.STOP, by, why)

    @property
    def unattended(self) -> bool:
        """Nobody can answer a pause or a confirmation (no terminal, no MQTT): such a wait
        stops the run after [interlocks] unanswered_pause_s (one under way: after that long
        from when this was set)."""
        return self._control.unanswered.limit is not None

    @unattended.setter
    def unattended(self, value: bool) -> None:
        self._control.set_unanswered_limit(self.rig.interlocks.unanswered_pause_s if value else None)

    def attended_again(self) -> None:
        """Someone can answer again at the run's own terminal (a background sweep brought to the
        foreground: `fg`): no longer unattended, and a wait under way drops its limit at once (its
        status said again without it), unlike after the broker's return, when nobody may watch yet."""
        self.unattended = False
        self._control.wake.set()  # the wait reads its limit again

    def confirm(self, step: str, by: str | None = None) -> None:
        """Confirm the manual setting `step` (e.g. 'manual:0003'); raises if not waiting for it.
        `by`: who sent each request (logged with the time in run.log and run.h5)."""
        self._control.confirm(step)
        self._command(RunCommand.CONFIRM, by, step)

    def _own_stop(self, by: str) -> None:
        """A stop the run asked itself (a wait nobody can answer): in the commands log too."""
        self._command(RunCommand.STOP, by)

    def _sender(self, by: str | None) -> str:
        return by or self.console_user or UNNAMED

    def _command(self, command: RunCommand, by: str | None, detail: str = "") -> None:
        if self._store is not None:
            self._write_later(
                functools.partial(self._store.command, command, by or self.console_user or UNNAMED, detail)
            )
