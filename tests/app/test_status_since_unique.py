"""Each state change of a run has its own ``since``: the dashboard's alarm id is
``<run id>@<since>`` of the status that raised it, so two changes in one millisecond (a
suspension and the failure after it, a clock set back) must not share one."""

from __future__ import annotations

import datetime as dt

from orbitrig.dashboard.alarms import AlarmBook, AlarmKind
from orbitrig.run.control import RunControl
from orbitrig.run.states import RunState
from rigunits import now_after, utc_iso

RUN = "rigA@2026-12-07T03:30:05.123Z"


def test_each_change_is_dated_after_the_one_before_and_raises_its_own_alarm():
    statuses: list[dict] = []
    control = RunControl(lambda state, message: statuses.append(status(control, state, message)), lambda *a, **k: None)
    ahead = utc_iso(dt.datetime.now(dt.timezone.utc) + dt.timedelta(seconds=5))
    control.fire("start", "run started")
    control.since = ahead  # the last change dated 5 s ahead of the clock (set back since, or this millisecond)
    control.fire("suspend", "suspended by interlock: lubricant supply pump is off")
    control.fire("fail", "interlock: lubricant supply pump is off for more than 120 s")
    suspended, failed = statuses[1]["since"], statuses[2]["since"]
    assert ahead < suspended < failed
    assert suspended == now_after(ahead) == utc_iso(dt.datetime.fromisoformat(ahead) + dt.timedelta(milliseconds=1))
    book = AlarmBook()
    for s in statuses:
        book.on_status(s)
    assert [(a["id"], a["kind"]) for a in reversed(book.listing())] == [
        (f"{RUN}@{suspended}", AlarmKind.TRIP),
        (f"{RUN}@{failed}", AlarmKind.TRIP),
    ]


def test_now_after_is_now_when_the_clock_is_later():
    before = utc_iso(dt.datetime.now(dt.timezone.utc) - dt.timedelta(seconds=1))
    got = dt.datetime.fromisoformat(now_after(before))
    assert abs((got - dt.datetime.now(dt.timezone.utc)).total_seconds()) < 1.0
    assert now_after("not a time") > before  # nothing to follow: now


def status(control: RunControl, state: RunState, message: str) -> dict:
    return {"state": str(state), "run_id": RUN, "since": control.since, "message": message}
