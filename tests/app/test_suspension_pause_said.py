"""A pause asked during an interlock suspension is said by the suspension's status, with who
asked, as a waiting status says one: the status said again (the same state and `since`) with
'; pause requested by ada: the run stays paused once the interlock clears', and again without it
when a resume withdraws the pause; a pause asked before the suspension and not reached yet is
said by its first status. Pure: the run's control and a supervisor holding the trip in force."""

from __future__ import annotations

import asyncio

import pytest

from orbitrig.dashboard.alarms import AlarmBook
from orbitrig.run.control import RunControl, StopRun
from orbitrig.run.interlocks import SUSPEND, Trip, TripKind
from orbitrig.run.states import PAUSED, RUNNING, STOPPING, RunState

PUMP = Trip(TripKind.SUPPLY_PUMP, SUSPEND, "lubricant supply pump is off")
SUSPENDED = "suspended by interlock: lubricant supply pump is off"
ASKED = "; pause requested by ada: the run stays paused once the interlock clears"


class Supervisor:
    """The InterlockSupervisor's face the run control reads: the trip in force and `clear`."""

    def __init__(self, trip: Trip):
        self.trip: Trip | None = trip
        self.clear = asyncio.Event()


def _control(said: list[tuple[RunState, str, str]]) -> RunControl:
    control = RunControl(lambda state, message: said.append((state, message, control.since)), lambda *a, **k: None)
    control.state = RUNNING
    return control


async def test_a_pause_asked_during_a_suspension_is_said_with_who_asked_until_a_resume_withdraws_it():
    said: list[tuple[RunState, str, str]] = []
    control, sup = _control(said), Supervisor(PUMP)
    held = asyncio.create_task(control.hold_while_suspended(sup, limit=60.0))
    await asyncio.sleep(0.05)
    assert said == [(PAUSED, SUSPENDED, control.since)]
    since = control.since
    assert control.request_pause("ada") == "the run stays paused once the interlock clears"
    assert said[1:] == [(PAUSED, SUSPENDED + ASKED, since)]  # the same status said again
    assert control.message == SUSPENDED + ASKED
    control.request_resume()  # withdraws it: said again without it
    assert said[2:] == [(PAUSED, SUSPENDED, since)]
    control.request_pause("bob")
    assert said[-1] == (PAUSED, SUSPENDED + ASKED.replace("ada", "bob"), since)
    control.request_stop("ada")  # the run stops: no status says the suspension again
    control.request_resume()
    assert [s[0] for s in said[4:]] == [STOPPING]
    sup.clear.set()
    with pytest.raises(StopRun):
        await asyncio.wait_for(held, 5.0)


async def test_a_pause_not_reached_before_the_suspension_is_said_by_its_first_status():
    said: list[tuple[RunState, str, str]] = []
    control, sup = _control(said), Supervisor(PUMP)
    control.request_pause("ada")  # running: held at the next safe point
    held = asyncio.create_task(control.hold_while_suspended(sup, limit=60.0))
    await asyncio.sleep(0.05)
    assert said == [(PAUSED, SUSPENDED + ASKED, control.since)]
    sup.trip = None
    sup.clear.set()
    await asyncio.sleep(0.05)
    assert [m for _, m, _ in said[1:]] == [
        "interlock cleared (supply_pump); the pause asked for meanwhile holds the run",
        "paused at a safe point (drives keep their speeds); asked by ada",
    ]
    control.request_resume()
    await asyncio.wait_for(held, 5.0)
    assert control.state == RUNNING


def test_the_alarm_of_a_suspension_first_seen_with_a_pause_pending_is_in_its_own_words():
    """The dashboard's alarm book, first handed the suspension's status said again with the pause (a
    dashboard started then): the alarm's text is the suspension's own, and the same condition in a later
    run (said without a pause) is that alarm's condition again."""
    said: list[tuple[RunState, str, str]] = []
    control = _control(said)
    control.fire("suspend", SUSPENDED)
    control.suspension, control.holding = PUMP, SUSPENDED
    control.request_pause("ada")
    book = AlarmBook()
    book.on_status({"state": "paused", "run_id": "r1", "since": said[-1][2], "message": said[-1][1]})
    book.on_status({"state": "idle", "run_id": "r1", "since": "2026-12-07T05:00:00.000Z", "message": "run stopped"})
    book.on_status({"state": "paused", "run_id": "r2", "since": "2026-12-07T05:01:00.000Z", "message": SUSPENDED})
    (later, first) = book.listing()
    assert said[-1][1] == SUSPENDED + ASKED and first["text"] == SUSPENDED, first
    assert (first["condition"], first["note"]) == ("active", "again in run r2"), first
