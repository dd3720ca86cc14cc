"""The operator's requests and the engine's waits: pause, resume, stop, abort, confirm, suspend.

`RunControl` owns the run state (changed only through the table of
orbitrig.run.states) and the requests. The point procedure calls its waits
at safe points; nothing here polls: every wait ends on an event (a request,
a confirmation, an interlock clearing).

- pause: held at the next safe point (before a manual setting, a speed change
  or the identification); drives keep their speeds. While the run waits for a manual
  setting's confirmation: held once it is confirmed (the waiting status says so meanwhile,
  `pause_when` says it to who asked). During an interlock suspension: held once the interlock
  clears (the suspension's status says so meanwhile; a resume withdraws it); refused (NotNow) while
  already held. Either status says who asked (`held_words`: '...; pause requested by ada: ...').
  Past the run's last safe point (the last point's, before its identification; the closing ramp)
  refused (NothingToPause, NOTHING_TO_PAUSE: the terminal's Ctrl-C and the service's reply say it).
- stop: finish the current orbit frequency, store it, end the run as stopped; a point left
  incomplete is measured again from its start by `orbitrig sweep --resume` (its blocks kept in aside/).
- abort: the engine cancels the run at once (emergency ramp), keeps what is complete; a run
  that goes on all the same (its cancel lost) ends at its next safe point or wait, before it
  commands the drives again.
- confirm(step): the operator confirms the manual setting the run waits for.
- doing: what the run does now ('measuring point 3 of 12: w1000rpm_...', `now_doing`): the
  message of every status into running (after a confirmation, a resume, an interlock clearing),
  and a running status said again when the next point starts, so that a retained status never
  keeps an answer given long ago ('confirmed manual:0000') as what the run is doing. Between two
  points (`between_points`) it is the next point ('next: point 4 of 12: ...'), said by a pause
  there (the operator's, or for lack of disk room) and by the resume that ends it.
- suspension: an interlock holds the run (state paused) until it clears; a resume with no
  pause to withdraw is refused (NotNow): the run resumes by itself.
- no room: too little free disk space for the next point pauses the run.
- stop now: a signal from the system (SIGTERM, SIGHUP, SIGQUIT): the engine cancels the
  run at once, the drives ramp to zero (not an emergency), the run ends stopped.
- nobody to answer (`set_unanswered_limit`, wall s): a pause or a confirmation that nobody
  can answer (no terminal, no MQTT) stops the run after that long (orbitrig.run.unanswered).

Every stop and abort keeps who asked for it (`stop_by`, `abort_by`: the sender as the
commands log records it, e.g. 'ada', 'service (supervision lost)', 'SIGTERM'): the run's
end message names it (orbitrig.run.ending).
"""

from __future__ import annotations

import asyncio
import time
from typing import Callable

from orbitrig.errors import OrbitrigError
from orbitrig.run.events import Note, NoteKind, Severity
from orbitrig.run.provenance import UNNAMED
from orbitrig.run.states import FAULTED, IDLE, PAUSE_REQUESTED, PAUSED, RUNNING, STOPPING, WAITING, RunState, next_state
from orbitrig.run.supervision import InterlockSupervisor
from orbitrig.run.interlocks import Trip
from orbitrig.run.unanswered import UnansweredWait
from rigunits import now_after, now_iso

#: what a stop does, said when it is asked for
STOP_WORDS = (
    "finishing the current orbit frequency, then both drives ramp to zero; a point left incomplete "
    "is measured again from its start by orbitrig sweep --resume (its blocks so far kept in aside/)"
)
#: what the run does once every point is measured: its closing ramp (`RunControl.closing_ramp`)
CLOSING_RAMP = "every point measured: both drives ramp to zero"
#: why a pause is refused once the run is past its last safe point (`RunControl.no_safe_point_left`):
#: the service's reply, the terminal's Ctrl-C
NOTHING_TO_PAUSE = (
    "cannot pause: every point is measured (the last one's identification and writes finishing), "
    "both drives ramp to zero and the run completes: no safe point is left to pause at"
)
#: when a pause asked during an interlock suspension takes effect (the reply, the suspension's status)
HELD_AFTER_SUSPENSION = "the run stays paused once the interlock clears"


class StopRun(Exception):
    """A stop request reached a safe point."""


class NotNow(OrbitrigError):
    """A request the run cannot take in its state; the message is the whole refusal."""


class NothingToPause(NotNow):
    """A pause asked once the run is past its last safe point (NOTHING_TO_PAUSE): a stop or an abort is still taken."""


class RunControl:
    def __init__(
        self,
        on_state: Callable[[RunState, str], None],
        note: Note,
        own_stop: Callable[[str], None] = lambda by: None,
    ):
        """``own_stop(by)``: records a stop this control asks itself (a wait nobody can answer)."""
        self._on_state = on_state
        self.note = note
        self._own_stop = own_stop
        self.state = IDLE
        self.message = ""
        self.since = now_iso()
        self.waiting_step: str | None = None
        self.holding = ""  # the waiting or suspended status's message, without the pause asked meanwhile
        self.timing: dict[str, float] = {}
        self.unanswered = UnansweredWait()  # the limit on waits nobody can answer
        self.reset()

    def reset(self) -> None:
        self.pause_requested = self.stop_requested = self.abort_requested = False
        self.pause_by: str | None = None  # who asked the pause, when the caller says
        self.stop_now: str | None = None  # why the run stops at once (a signal)
        self.stop_by: str | None = None  # who asked the first stop (as the commands log records it)
        self.abort_by: str | None = None  # who asked the abort (set by the engine as it asks)
        self.confirmed: str | None = None
        self.doing = ""  # what the run does now (now_doing), said in its running statuses
        self.closing = False  # past its last safe point (`no_safe_point_left`): nothing left to pause
        self.next_label: str | None = None  # between points: the next point's label (between_points)
        self.suspension: Trip | None = None  # the interlock holding the run now
        self.held_for_room = False  # paused for too little free disk space
        self.wake = asyncio.Event()
        self.aborted = asyncio.Event()  # set by an abort: a ramp stop under way becomes an emergency stop

    def fire(self, event: str, message: str) -> None:
        """Change state by the table; tell the engine. Into running: what the run does now follows
        the message ('confirmed manual:0002; measuring point 3 of 12: ...')."""
        self.state = next_state(self.state, event)
        if self.state == RUNNING and self.doing:
            message = f"{message}; {self.doing}"
        self.message, self.since = message, now_after(self.since)  # one per change: an alarm's id holds it
        self._on_state(self.state, message)

    def now_doing(self, what: str) -> None:
        """The run does `what` from now on: a running status says it at once (the same state and
        `since`); in another state, the status into running says it (`fire`)."""
        self.doing, self.next_label = what, None
        if self.state == RUNNING:
            self.message = what
            self._on_state(self.state, what)

    def no_safe_point_left(self) -> None:
        """The run is past its last safe point (the last point's, before its identification; or its
        closing ramp, with no point left to measure): a pause from here on is refused (NothingToPause)."""
        self.closing = True

    def closing_ramp(self) -> None:
        """Every point is measured: both drives ramp to zero at the end (CLOSING_RAMP said), nothing left to pause."""
        self.no_safe_point_left()
        self.now_doing(CLOSING_RAMP)

    def between_points(self, label: str, what: str) -> None:
        """The point before is done, the point `label` comes next (`what`: 'next: point 4 of 12: ...'):
        a pause here and the resume from it say that one, not the point done (no status at once)."""
        self.doing, self.next_label = what, label

    def _next(self) -> str:
        """'; next: point 4 of 12: ...' for a pause between points, '' within a point."""
        return f"; {self.doing}" if self.next_label is not None else ""

    # ---------------------------------------------------------- requests
    def request_pause(self, by: str | None = None) -> str:
        """Pause at the next safe point, once the manual setting the run waits for is confirmed,
        or once the interlock suspending the run clears; NotNow while an operator's pause holds
        the run, NothingToPause past its last safe point (`by`: who asks, for the pause's status).
        Returns when it takes effect (pause_when)."""
        if self.closing:
            raise NothingToPause(NOTHING_TO_PAUSE)
        when = self.pause_when()
        if self.state in (RUNNING, WAITING) or self.suspension is not None:
            self.pause_requested, self.pause_by = True, by
            self.note(f"pause requested: {when}")
            self._restate_held()
        elif self.state == PAUSED and not self.held_for_room:
            raise NotNow("cannot pause while the run is paused (resume to go on)")
        self.wake.set()
        return when

    def pause_when(self) -> str:
        """When a pause asked now takes effect, in the operator's words (the reply to the pause)."""
        if self.suspension is not None:
            return HELD_AFTER_SUSPENSION
        if self.state == WAITING and self.waiting_step is not None:
            return (
                f"the run pauses once {self.waiting_step} is confirmed "
                "(until then it waits for the operator; a resume withdraws the pause)"
            )
        if self.state == PAUSED:
            return "the run stays paused until resumed"
        return "the run pauses at its next safe point"

    def held_words(self) -> str:
        """The message of the status holding the run (a wait for a confirmation, an interlock
        suspension: `holding`), with a pause asked meanwhile and who asked it."""
        if self.suspension is not None:
            until = HELD_AFTER_SUSPENSION
        elif self.waiting_step is not None:
            until = f"the run pauses once {self.waiting_step} is confirmed"
        else:
            return self.holding
        by = f" by {self.pause_by}" if self.pause_by else ""
        return f"{self.holding}{PAUSE_REQUESTED}{by}: {until}" if self.pause_requested else self.holding

    def _restate_held(self) -> None:
        """While waiting or suspended, the status said again (the same state and `since`) with what it now holds."""
        held = self.state == WAITING or (self.state == PAUSED and self.suspension is not None)
        if held and self.message != (words := self.held_words()):
            self.message = words
            self._on_state(self.state, words)

    @property
    def pause_pending(self) -> bool:
        """A pause asked for and not yet reached (the run is running, waiting or suspended)."""
        return self.pause_requested and (self.state in (RUNNING, WAITING) or self.suspension is not None)

    def request_resume(self) -> None:
        """Resume a paused run, or withdraw a pause not yet reached (the run then goes on); NotNow
        during an interlock suspension with no pause to withdraw (the run resumes by itself)."""
        trip = self.suspension
        if trip is not None and not self.pause_requested:
            raise NotNow(
                f"cannot resume: the run is suspended by interlock ({trip.message}); "
                "it resumes by itself when that clears"
            )
        if self.pause_pending:
            self.note("pause withdrawn (it had not been reached)")
        self.pause_requested = False
        self._restate_held()
        self.wake.set()

    def request_stop(self, by: str = UNNAMED, message: str = "") -> None:
        """Stop at the next safe point; `by`: who asks (the first stop's sender is kept)."""
        if self.state in (IDLE, FAULTED):
            return
        self.stop_requested = True
        self.stop_by = self.stop_by or by
        self.wake.set()
        if self.state != STOPPING:
            self.fire("stop", message or f"stop requested by {by}: {STOP_WORDS}")

    @property
    def abort_starts(self) -> bool:
        """An abort asked now would start one (the run is active and not aborting yet)."""
        return self.state not in (IDLE, FAULTED) and not self.abort_requested

    @property
    def stop_now_starts(self) -> bool:
        """A stop at once asked now would start one (active, not aborting, not stopping at once)."""
        return self.abort_starts and self.stop_now is None

    def request_stop_now(self, why: str) -> bool:
        """Stop at once with a ramp (`why`: e.g. 'SIGTERM'); True if the engine is to cancel the run."""
        if not self.stop_now_starts:
            return False
        self.stop_now = why
        self.request_stop(why, f"{why}: stopping now, both drives ramp to zero")
        return True

    def request_abort(self) -> bool:
        """True if this request starts an abort (the engine then cancels the run); who asks
        is `abort_by`, set by the engine before."""
        if not self.abort_starts:
            return False
        self.abort_requested = True
        self.aborted.set()
        self.wake.set()
        self.fire("abort", f"abort requested by {self.abort_by or UNNAMED}: emergency ramp down")
        return True

    def confirm(self, step: str) -> None:
        """Confirm the manual setting `step` (e.g. 'manual:0003'); raises if not waiting for it."""
        if self.state != WAITING or self.waiting_step is None:
            raise OrbitrigError(f"not waiting for a confirmation (state {self.state})")
        if step != self.waiting_step:
            raise OrbitrigError(f"waiting for '{self.waiting_step}', not '{step}'")
        self.confirmed, self.waiting_step = step, None
        self.fire("confirm", f"confirmed {step}")
        self.wake.set()

    def set_unanswered_limit(self, limit: float | None) -> None:
        """Nobody can answer a pause or a confirmation from now on (`limit` wall s), or someone
        can (None). A wait under way takes a limit at once, counted from now; one under way when
        the limit is lifted keeps it until its next wake (a request)."""
        self.unanswered.set_limit(limit)
        if limit is not None:
            self.wake.set()

    # -------------------------------------------------------------- waits
    def end_if_aborted(self) -> None:
        """An aborted run's body ends here (cancelled) if its cancel was lost and it went on."""
        if self.abort_requested:
            raise asyncio.CancelledError("the run was aborted")

    def add_time(self, key: str, t0: float) -> None:
        self.timing[key] = self.timing.get(key, 0.0) + time.monotonic() - t0

    async def _until_resumed(self, t0: float) -> None:
        while self.pause_requested and not self.stop_requested:
            await self._wait_answer(t0)

    async def _wait_answer(self, t0: float) -> None:
        """Until the next request; if nobody can answer, a stop once the unanswered limit has
        passed since `t0` (the wait's start) or since the limit was set, the later. The status
        is stated again when that deadline changes."""
        self.end_if_aborted()
        self.wake.clear()
        limit = self.unanswered.limit
        if (restated := self.unanswered.restated(t0)) is not None:
            self.message = restated
            if self.state == WAITING:  # with the pause asked meanwhile
                self.holding, self.message = restated, self.held_words()
            self._on_state(self.state, self.message)  # the same state, its deadline changed
        if await self.unanswered.until_woken(self.wake, t0) and limit is not None and not self.stop_requested:
            self.stop_unanswered(*self.unanswered.stop_words(self.state, limit))

    def stop_unanswered(self, by: str, why: str) -> None:
        """Nobody answered a wait in time (`why`; `by` in the commands log too): the run stops."""
        self.request_stop(by, f"{why}: stopping the run (continue later with --resume)")
        self._own_stop(by)

    async def safe_point(self, allow_stop: bool = True) -> None:
        """Honour an abort (cancelled), a stop (StopRun) or a pause here."""
        self.end_if_aborted()
        if self.stop_requested and allow_stop:
            raise StopRun
        if not self.pause_requested or self.stop_requested:
            return
        t0 = time.monotonic()
        asked = f"; asked by {self.pause_by}" if self.pause_by else ""
        self.fire(
            "pause",
            self.unanswered.held(
                f"paused at a safe point (drives keep their speeds){asked}{self._next()}", "resumed", t0
            ),
        )
        await self._until_resumed(t0)
        if self.stop_requested:
            if allow_stop:
                raise StopRun
            return
        self.fire("resume", "resumed")

    async def ask(self, step_id: str, message: str) -> None:
        """Wait until the operator confirms `step_id` (StopRun on a stop)."""
        if self.stop_requested:
            raise StopRun
        t0 = time.monotonic()
        self.waiting_step, self.confirmed = step_id, None
        # the operator (terminal or MQTT) confirms by this id: {"cmd": "confirm", "step": ...}
        self.holding = self.unanswered.held(f"{message} (confirm step {step_id!r})", "confirmed", t0)
        self.fire("ask", self.held_words())
        try:
            while self.confirmed != step_id:
                if self.stop_requested:
                    raise StopRun
                await self._wait_answer(t0)
        finally:
            self.waiting_step = None
        self.add_time("confirm", t0)
        await self.safe_point()

    async def hold_for_room(self, problem: Callable[[], str | None]) -> None:
        """Paused while `problem()` says the disk has no room for the next point (what to do about it); resume
        re-checks. `problem` may hang (a network share): no stop waits for it (orbitrig.run.room_check)."""
        from orbitrig.run.room_check import checked

        why = await checked(self, problem)
        if why is None:
            return
        if self.stop_requested:
            raise StopRun
        t0 = time.monotonic()
        self.fire("no_room", self.unanswered.held(f"paused: {why}{self._next()}", "resumed", t0))
        self.held_for_room = True
        try:
            while why is not None:
                self.pause_requested = True
                await self._until_resumed(t0)
                if self.stop_requested:
                    raise StopRun
                why = await checked(self, problem)
                if why is not None:
                    self.note(f"still paused: {why}", Severity.WARNING, NoteKind.DISK_FULL)
        finally:
            self.held_for_room = False
        self.fire("resume", "resumed: there is room for the next point")

    async def hold_while_suspended(self, sup: InterlockSupervisor, limit: float) -> None:
        """Paused while a suspend trip is in force (RunFailed after `limit` wall s); then held on if a
        pause was asked meanwhile; a stop or an abort asked meanwhile ends it (orbitrig.run.suspension)."""
        from orbitrig.run.suspension import hold

        await hold(self, sup, limit)
