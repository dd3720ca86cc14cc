"""The run engine's states and transitions: one table, like bluesky's RunEngine.

A state changes only through `next_state(state, event)`; an event the table
does not list for the state is a bug in the engine (`LookupError`).

States (the `state` of the MQTT status topic):

- idle: no run; faulted: the last run failed (a new run may start);
- running: the plan is being executed;
- paused: held at a safe point, drives keep their speeds (an operator pause,
  an interlock suspension or too little free disk space; the message says which);
- waiting: waiting for the operator to confirm a manual setting;
- stopping: a stop or an abort is under way, or the run is ending and the
  drives are being made safe.

Outcomes of a run: completed | stopped | aborted | failed.
"""

from __future__ import annotations

from enum import StrEnum

from orbitrig.store.status import RunStatus


class _Word(StrEnum):
    """A closed set of words: equal to, printed and repr'd as its string (messages unchanged)."""

    __repr__ = str.__repr__


class RunState(_Word):
    """A state of the run engine; equal to its string in payloads and files."""

    IDLE = "idle"
    RUNNING = "running"
    PAUSED = "paused"
    WAITING = "waiting"
    STOPPING = "stopping"
    FAULTED = "faulted"


class Outcome(_Word):
    """How a run ended: the final statuses the store records (its RunStatus words;
    `running` until then)."""

    COMPLETED = RunStatus.COMPLETED.value
    STOPPED = RunStatus.STOPPED.value
    ABORTED = RunStatus.ABORTED.value
    FAILED = RunStatus.FAILED.value


def stored_status(outcome: Outcome) -> RunStatus:
    """The status the store records for a run that ended with `outcome`."""
    return RunStatus(outcome.value)


class ConfirmMode(_Word):
    """Who confirms a manual setting: the terminal's operator (prompt), an MQTT
    `confirm` command (remote), or nobody: the simulator sets it (auto)."""

    PROMPT = "prompt"
    REMOTE = "remote"
    AUTO = "auto"


class RunCommand(_Word):
    """The commands that change a run (the MQTT `cmd` words, the journal's command lines)."""

    START = "start"
    CONFIRM = "confirm"
    PAUSE = "pause"
    RESUME = "resume"
    STOP = "stop"
    ABORT = "abort"


#: what a suspension's status says first ('suspended by interlock: <cause>'; the dashboard's alarms and badge read it)
SUSPENDED = "suspended by interlock:"
#: what the status says first when the interlock of a suspension clears ('interlock cleared (<kind>)...')
CLEARED = "interlock cleared"
#: what a held status's message says after its own words when a pause is asked meanwhile ('; pause requested by ada: ...')
PAUSE_REQUESTED = "; pause requested"
#: a completed run's end message; a stopped or aborted run with every point complete, and a resume
#: that only consolidated run.h5, start their own with them ('all points completed; stopped by ada')
ALL_COMPLETED = "all points completed"

IDLE, RUNNING, PAUSED, WAITING, STOPPING, FAULTED = RunState
STATES = tuple(RunState)
COMPLETED, STOPPED, ABORTED, FAILED = Outcome

#: what makes the engine change state, and what it means
EVENTS: dict[str, str] = {
    "start": "a run starts",
    "pause": "an operator pause reaches a safe point",
    "suspend": "an interlock trips (suspend action)",
    "no_room": "too little free disk space for the next point",
    "resume": "the operator resumes (or the free space is back)",
    "clear": "the interlock condition clears",
    "ask": "a manual setting needs the operator's confirmation",
    "confirm": "the operator confirms the manual setting",
    "stop": "the operator asks to stop (finish the current orbit frequency)",
    "abort": "the operator asks to abort (emergency ramp at once)",
    "finish": "the plan is done or stopped: both drives are made safe",
    "fail": "a failure ends the run (interlock, verification, hardware, storage)",
    "done": "the drives are safe and the run file is closed",
}

_ACTIVE = (RUNNING, PAUSED, WAITING)

#: (state, event) -> next state
TRANSITIONS: dict[tuple[RunState, str], RunState] = {
    (IDLE, "start"): RUNNING,
    (FAULTED, "start"): RUNNING,
    (RUNNING, "pause"): PAUSED,
    (RUNNING, "suspend"): PAUSED,
    (RUNNING, "no_room"): PAUSED,
    (PAUSED, "resume"): RUNNING,
    (PAUSED, "clear"): RUNNING,
    (RUNNING, "ask"): WAITING,
    (WAITING, "confirm"): RUNNING,
    **{(s, "stop"): STOPPING for s in _ACTIVE},
    **{(s, "abort"): STOPPING for s in (*_ACTIVE, STOPPING)},
    **{(s, "finish"): STOPPING for s in (*_ACTIVE, STOPPING)},
    **{(s, "fail"): FAULTED for s in (*_ACTIVE, STOPPING)},
    (STOPPING, "done"): IDLE,
}


def next_state(state: RunState, event: str) -> RunState:
    """The state after `event` in `state`; LookupError if the table has no such transition."""
    try:
        return TRANSITIONS[(state, event)]
    except KeyError:
        raise LookupError(f"run engine: no transition for event {event!r} in state {state!r}") from None


def transition_table() -> str:
    """The table as Markdown rows (docs/architecture.md holds a copy, checked by a test)."""
    rows = ["| state | event | next state | when |", "|---|---|---|---|"]
    for (state, event), new in TRANSITIONS.items():
        rows.append(f"| {state} | {event} | {new} | {EVENTS[event]} |")
    return "\n".join(rows)
