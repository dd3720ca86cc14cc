"""Latched alarms of one rig: interlock trips and failed runs, kept until acknowledged.

Alarms are raised from the service's status (docs/protocols/mqtt.md): a status whose
message says ``suspended by interlock: ...`` raises a *trip*; a ``faulted`` status raises a
*trip* when an interlock ended the run, else a *fault*. The alarm's id is
``<run_id>@<since>`` of the status that raised it, the same in every dashboard. It stays
latched (listed, unacknowledged) until someone acknowledges it, also after its condition
clears (``interlock cleared ...`` marks the run's trips cleared).

An acknowledgement is a message on ``<prefix>/ack`` (this project's extension of the
topic tree): ``{"alarm": "<id>", "by": "<user>", "at": "<ISO-8601 time>", "id": "<nonce>"}``.
The broker's ACL lets operators publish it; every dashboard on the broker applies it.
At most ``limit`` alarms are kept: the oldest acknowledged ones go first.

The dashboard server keeps one book per rig (:class:`AlarmShelf`), shared by every session
watching that rig: a latched alarm outlives the session that saw it raised (sign-out, idle
expiry, a switch to another rig and back) until the dashboard server stops.
"""

from __future__ import annotations

import dataclasses
from enum import StrEnum
from typing import Any

from orbitrig.service.protocol import RunState

SUSPENDED = "suspended by interlock:"
CLEARED = "interlock cleared"


class AlarmKind(StrEnum):
    """What raised an alarm: an interlock trip, or a run that failed for another reason."""

    TRIP = "trip"
    FAULT = "fault"


@dataclasses.dataclass
class Alarm:
    """One latched alarm; times as the service and the acknowledging page wrote them (ISO-8601)."""

    id: str
    kind: AlarmKind
    text: str
    since: str
    run_id: str | None
    cleared: bool = False
    acked_by: str | None = None
    acked_at: str | None = None


def _raised(status: dict[str, Any]) -> Alarm | None:
    """The alarm a status raises, if any."""
    message, state = str(status.get("message") or ""), status.get("state")
    run_id, since = status.get("run_id"), str(status.get("since") or "")
    if message.startswith(SUSPENDED):
        kind = AlarmKind.TRIP
    elif state == RunState.FAULTED:
        kind = AlarmKind.TRIP if "interlock" in message else AlarmKind.FAULT
    else:
        return None
    return Alarm(f"{run_id}@{since}", kind, message, since, run_id)


class AlarmBook:
    """The alarms of one rig as the dashboard server has seen them; ``version`` counts its changes."""

    def __init__(self, limit: int = 200):
        self.limit = limit
        self.alarms: dict[str, Alarm] = {}
        self.version = 0

    def on_status(self, status: dict[str, Any]) -> bool:
        """Raise or clear alarms from a status; True when the list changed."""
        alarm = _raised(status)
        if alarm is not None:
            if alarm.id in self.alarms:
                return False
            self.alarms[alarm.id] = alarm
            self._bound()
            self.version += 1
            return True
        if str(status.get("message") or "").startswith(CLEARED) or status.get("state") == RunState.IDLE:
            stale = [
                a
                for a in self.alarms.values()
                if a.kind == AlarmKind.TRIP and not a.cleared and a.run_id == status.get("run_id")
            ]
            for a in stale:
                a.cleared = True
            self.version += bool(stale)
            return bool(stale)
        return False

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
        """Every alarm kept, newest first."""
        return [dataclasses.asdict(a) for a in reversed(self.alarms.values())]


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
