"""The rig service's budget of the run's warnings on <prefix>/note: at most BURST in any WINDOW_S s
(a flood never fills a subscriber's queue at the broker), the next one published after a pause
saying how many were withheld, and a warning again once the oldest has left the window."""

from __future__ import annotations

from orbitrig.service import protocol as proto
from orbitrig.run.events import NoteKind
from orbitrig.service.note_budget import BURST, WINDOW_S, NoteBudget


class Clock:
    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


def test_a_flood_of_warnings_is_capped_and_the_withheld_are_counted():
    clock = Clock()
    budget = NoteBudget(clock=clock)
    admitted = [budget.admit() for _ in range(BURST + 25)]  # 35 in the same instant
    assert admitted[:BURST] == [0] * BURST and admitted[BURST:] == [None] * 25
    clock.t += WINDOW_S - 0.001  # the window still holds all ten
    assert budget.admit() is None
    clock.t += 0.001
    assert budget.admit() == 26  # the first one published again says how many were not
    assert budget.admit() == 0


def test_warnings_one_a_block_at_a_steady_pace_are_all_published():
    clock = Clock()
    budget = NoteBudget(clock=clock)
    period = WINDOW_S / BURST  # 6 s a block: the budget's own pace
    admitted = []
    for _ in range(100):
        clock.t += period
        admitted.append(budget.admit())
    assert admitted == [0] * 100


def test_the_note_payload_names_its_withheld_warnings_only_when_there_were():
    at = "2026-12-05T12:31:13.442Z"
    assert proto.note_payload("r@x", "warning", "A/D link dropped", at) == (
        b'{"run_id":"r@x","severity":"warning","message":"A/D link dropped","at":"2026-12-05T12:31:13.442Z"}'
    )
    assert b'"withheld":3}' in proto.note_payload("r@x", "warning", "m", at, 3)


def test_the_withheld_are_counted_by_kind_until_said_and_the_run_totals_kept():
    clock = Clock()
    budget = NoteBudget(burst=2, clock=clock)
    drop, retry = NoteKind.ADC_LINK_DROP, NoteKind.ACQUISITION_RETRIED
    assert [budget.admit(k) for k in (drop, drop, drop, retry, drop)] == [0, 0, None, None, None]
    assert budget.withheld_kinds == {"A/D link drop": 2, "acquisition retried": 1}
    clock.t += WINDOW_S
    assert budget.admit(retry) == 3 and budget.released_kinds == {"A/D link drop": 2, "acquisition retried": 1}
    assert budget.admit(retry) == 0 and budget.released_kinds == {}
    assert budget.admit(retry) is None  # withheld at the end: said by the run's closing note
    assert budget.take_withheld() == (1, {"acquisition retried": 1}) and budget.take_withheld() == (0, {})
    assert budget.totals() == {
        "said": 8,
        "published": 4,
        "withheld": 4,
        "withheld_kinds": {"A/D link drop": 2, "acquisition retried": 2},
    }


def test_the_note_payload_carries_the_runs_count_and_the_kinds_withheld():
    at = "2026-12-05T12:31:13.442Z"
    payload = proto.note_payload("r@x", "warning", "m", at, 3, {"A/D link drop": 3}, said=12)
    assert payload == (
        b'{"run_id":"r@x","severity":"warning","message":"m","at":"2026-12-05T12:31:13.442Z","said":12,'
        b'"withheld":3,"withheld_kinds":{"A/D link drop":3}}'
    )
    assert b"withheld" not in proto.note_payload("r@x", "warning", "m", at, 0, {}, said=1)
