"""Latched alarms of one rig: interlock trips and failed runs, kept until acknowledged.

Alarms are raised from the service's status (docs/protocols/mqtt.md): a status whose
message says ``suspended by interlock: ...`` raises a *trip*; a ``faulted`` status raises a
*trip* when an interlock ended the run, else a *fault*. The alarm's id is
``<run_id>@<since>`` of the status that raised it, the same in every dashboard. It stays
latched (listed, unacknowledged) until someone acknowledges it, also after its condition
clears.

Its *condition* follows what the statuses show, and says so when they show nothing:

- ``active``: a suspension's status said so, and no later status of that run said otherwise;
- ``cleared``: the run said ``interlock cleared ...``; or a later run completed (a run that
  completes has no interlock in force);
- ``unknown``: the run watching the condition ended (stopped, failed, another run or no run
  reported instead) or the rig service went offline: nobody tells the condition any more.
  A failed run's own alarm starts so. A later run suspended by the same condition makes it
  ``active`` again (watched by that run), and that run's ``interlock cleared`` clears it.

An acknowledgement is a message on ``<prefix>/ack`` (this project's extension of the
topic tree): ``{"alarm": "<id>", "by": "<user>", "at": "<ISO-8601 time>", "id": "<nonce>"}``.
The broker's ACL lets operators publish it; every dashboard on the broker applies it.
At most ``limit`` alarms are kept: the oldest acknowledged ones go first.

The dashboard server keeps one book per rig (:class:`AlarmShelf`), shared by every session
watching that rig: a latched alarm outlives the session that saw it raised (sign-out, idle
expiry, a switch to another rig and back) until the dashboard server stops. Every session
hands the book the statuses it receives; the book applies each status once (``on_status``
with the session's place in the book's log), however many sessions hand it on.
"""

from __future__ import annotations

import collections
import dataclasses
import json
import re
from enum import StrEnum
from collections.abc import Callable
from typing import Any

#: a suspension's status (SUSPENDED), what it says after its own words while a pause asked meanwhile
#: is pending (PAUSE_REQUESTED, '; pause requested by ada: ...': no part of the alarm), and the
#: status of its interlock cleared (CLEARED): the run's words (orbitrig.run.states)
from orbitrig.service.protocol import CLEARED, OFFLINE, PAUSE_REQUESTED, SUSPENDED, RunState

COMPLETED = "run completed"  # the idle status of a run that completed (docs/protocols/mqtt.md)
ENDED = (RunState.IDLE, RunState.FAULTED, OFFLINE)
_FAILED_BY = re.compile(r"\binterlock: (.*?)(?: for more than [\d.]+ s)?$")
LOG_LENGTH = 256  # statuses the book remembers to apply each once


class AlarmKind(StrEnum):
    """What raised an alarm: an interlock trip, or a run that failed for another reason."""

    TRIP = "trip"
    FAULT = "fault"


class Condition(StrEnum):
    """Whether what raised an alarm is still there, as far as the statuses tell."""

    ACTIVE = "active"
    CLEARED = "cleared"
    UNKNOWN = "unknown"


@dataclasses.dataclass
class Alarm:
    """One latched alarm; times as the service and the acknowledging page wrote them (ISO-8601).
    ``note`` says what the condition rests on (empty: the alarm's own run said it)."""

    id: str
    kind: AlarmKind
    text: str
    since: str
    run_id: str | None
    condition: Condition = Condition.ACTIVE
    note: str = ""
    acked_by: str | None = None
    acked_at: str | None = None
    cause: str = ""  # the interlock's own words: the same condition in a later run
    watched_in: str | None = None  # the run whose statuses tell the condition now


def _cause(message: str) -> str:
    if message.startswith(SUSPENDED):
        return message[len(SUSPENDED) :].strip()
    found = _FAILED_BY.search(message)
    return found.group(1) if found else message


def _raised(status: dict[str, Any]) -> Alarm | None:
    """The alarm a status raises, if any (a suspension's: its own words, without a pause pending)."""
    message, state = str(status.get("message") or ""), status.get("state")
    run_id, since = status.get("run_id"), str(status.get("since") or "")
    if message.startswith(SUSPENDED):
        message = message.split(PAUSE_REQUESTED, 1)[0]
        kind, condition, note = AlarmKind.TRIP, Condition.ACTIVE, ""
    elif state == RunState.FAULTED:
        kind = AlarmKind.TRIP if "interlock" in message else AlarmKind.FAULT
        condition, note = Condition.UNKNOWN, "not known since the run ended"
    else:
        return None
    return Alarm(
        f"{run_id}@{since}", kind, message, since, run_id, condition, note, cause=_cause(message), watched_in=run_id
    )


class AlarmBook:
    """The alarms of one rig as the dashboard server has seen them; ``version`` counts its changes."""

    def __init__(self, limit: int = 200):
        self.limit = limit
        self.alarms: dict[str, Alarm] = {}
        self.version = 0
        self._log: collections.deque[tuple[int, str]] = collections.deque(maxlen=LOG_LENGTH)
        self._seq = 0

    def on_status(self, status: dict[str, Any], seen: int | None = None) -> tuple[bool, int]:
        """Raise alarms, or change their condition, from a status handed on by a session: True when the
        list changed, and the session's new place in the book's log. ``seen``: its place after the last
        status it handed on (None: its first on this rig). A status another session handed on already
        (found in the log after ``seen``; the latest one when ``seen`` is None) is not applied again: a
        session behind the others must not take the list back to an older state."""
        key = json.dumps(status, sort_keys=True, default=str)
        for seq, logged in self._log:
            if logged == key and (seq == self._seq if seen is None else seq > seen):
                return False, seq
        self._seq += 1
        self._log.append((self._seq, key))
        changed = self._apply(status)
        self.version += changed
        return changed, self._seq

    def _apply(self, status: dict[str, Any]) -> bool:
        message, state, run_id = str(status.get("message") or ""), status.get("state"), status.get("run_id")
        changed = False
        if state != OFFLINE:  # another run (or none) reports: the runs watching conditions before have ended
            changed |= self._untold(lambda a: a.watched_in != run_id, _ended)
        alarm = _raised(status)
        if alarm is not None:
            changed |= self._raise(alarm)
        if message.startswith(CLEARED):
            for a in self._open(lambda a: a.condition == Condition.ACTIVE and a.watched_in == run_id):
                a.condition, a.note, changed = Condition.CLEARED, _in_run(a, run_id), True
        elif state == RunState.IDLE and message.startswith(COMPLETED):
            for a in self._open(lambda a: a.condition != Condition.CLEARED):
                a.condition, a.note, changed = Condition.CLEARED, _completed(a, run_id), True
        elif state == OFFLINE:
            changed |= self._untold(lambda a: True, lambda a: "the rig service went offline")
        elif state in ENDED:
            changed |= self._untold(lambda a: a.watched_in == run_id, _ended)
        return changed

    def _open(self, pred: Callable[[Alarm], bool]) -> list[Alarm]:
        return [a for a in self.alarms.values() if pred(a)]

    def _untold(self, which: Callable[[Alarm], bool], note: Callable[[Alarm], str]) -> bool:
        """The active alarms ``which`` picks become unknown (``note(alarm)``: why)."""
        gone = self._open(lambda a: a.condition == Condition.ACTIVE and which(a))
        for a in gone:
            a.condition, a.note = Condition.UNKNOWN, note(a)
        return bool(gone)

    def _raise(self, alarm: Alarm) -> bool:
        old = self.alarms.get(alarm.id)
        if old is not None:  # the same status again (the service reports it again): its word holds
            if alarm.condition != Condition.ACTIVE or old.condition == Condition.ACTIVE:
                return False
            old.condition, old.note, old.watched_in = Condition.ACTIVE, "", old.run_id
            return True
        if alarm.condition == Condition.ACTIVE:  # the same condition, not known since an earlier run: here again
            for a in self._open(lambda a: a.condition == Condition.UNKNOWN and a.cause == alarm.cause):
                a.condition, a.note, a.watched_in = Condition.ACTIVE, f"again in run {alarm.run_id}", alarm.run_id
        self.alarms[alarm.id] = alarm
        self._bound()
        return True

    def on_ack(self, ack: dict[str, Any]) -> bool:
        """Apply an acknowledgement from ``<prefix>/ack``; True when the list changed."""
        alarm = self.alarms.get(str(ack.get("alarm")))
        by, at = ack.get("by"), ack.get("at")
        if alarm is None or alarm.acked_by is not None or not isinstance(by, str) or not by:
            return False
        alarm.acked_by, alarm.acked_at = by[:64], str(at or "")[:40]
        self.version += 1
        return True

    def _bound(self) -> None:
        while len(self.alarms) > self.limit:
            acked = [k for k, a in self.alarms.items() if a.acked_by is not None]
            del self.alarms[(acked or list(self.alarms))[0]]

    def listing(self) -> list[dict[str, Any]]:
        """Every alarm kept, newest first (what the page shows of each)."""
        hidden = ("cause", "watched_in")
        return [
            {k: v for k, v in dataclasses.asdict(a).items() if k not in hidden} for a in reversed(self.alarms.values())
        ]


def _ended(alarm: Alarm) -> str:
    run = alarm.watched_in
    return "not known since the run ended" if run == alarm.run_id else f"not known since run {run} ended"


def _in_run(alarm: Alarm, run_id: Any) -> str:
    return "" if run_id == alarm.run_id else f"in run {run_id}"


def _completed(alarm: Alarm, run_id: Any) -> str:
    return "the run completed" if run_id == alarm.run_id else f"run {run_id} completed since"


class AlarmShelf:
    """The alarm book of every rig the dashboard's sessions have watched, by topic prefix (at most
    ``limit`` rigs: beyond, the book that has longest had nothing unacknowledged goes)."""

    def __init__(self, limit: int = 256):
        self.limit = limit
        self.books: dict[str, AlarmBook] = {}

    def book(self, prefix: str) -> AlarmBook:
        """The book of the rig under ``prefix`` (a new one the first time)."""
        book = self.books.get(prefix)
        if book is None:
            if len(self.books) >= self.limit:
                quiet = [k for k, b in self.books.items() if all(a.acked_by for a in b.alarms.values())]
                del self.books[(quiet or list(self.books))[0]]
            book = self.books[prefix] = AlarmBook()
        return book
