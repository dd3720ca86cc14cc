"""What a status names between two points, on the real engine and simulator: a pause there (the
operator's, or for lack of disk room) and the resume from it name the next point to measure, in
the message and in `point_label` (with `between_points`), never the point just done; the next
point's start then says it as measured, and the closing ramp names none.

The disk's free space is injected (RunStore.free_bytes), as in test_run_storage_safety; the
operator's pause is asked as the first point completes (PointRecord.complete_point, the point's
last step: its safe points are behind it)."""

import asyncio

import pytest

from orbitrig import config as cfg
from orbitrig.run.engine import StatusEvent
from orbitrig.run.plan import make_plan
from orbitrig.run.point_record import PointRecord
from orbitrig.store.writer import RunStore
from support.sweep_helpers import running, small_matrix, wait_for

pytestmark = pytest.mark.timeout(120)

#: two points, no manual setting between them (the spin changes)
MATRIX = small_matrix(spin_rpm=[1000.0, 2000.0])
FIRST, SECOND = (p.label for p in make_plan(MATRIX, cfg.load_rig()).points)


def statuses(rec) -> list[tuple[str, str, str | None, bool]]:
    """The run's statuses, but the closing stop's wait for the storage in flight (said after 1 s:
    the last point's identification takes that long with both cores busy)."""
    said = [(e.state, e.message, e.point_label, e.between_points) for e in rec.events if isinstance(e, StatusEvent)]
    return [s for s in said if "waiting for the storage in flight" not in s[1]]


def after_first_point(said: list[tuple[str, str, str | None, bool]]) -> list[tuple[str, str, str | None, bool]]:
    """The statuses from the first after the first point's start (its measuring status)."""
    first = said.index(("running", f"measuring point 1 of 2: {FIRST} (point 0000)", FIRST, False))
    return said[first + 1 :]


async def test_a_pause_between_points_names_the_next_point(tmp_path, monkeypatch):
    complete_point, engines = PointRecord.complete_point, []

    async def then_pause(self, step, ps):
        await complete_point(self, step, ps)
        if ps.point.index == 0:
            engines[0].request_pause("ada")  # its safe points behind: held before the next point

    monkeypatch.setattr(PointRecord, "complete_point", then_pause)
    async with running(tmp_path, MATRIX) as (sim, eng, rec, run):
        engines.append(eng)
        await wait_for(lambda: eng.state == "paused", timeout=60, what="paused between the points")
        eng.request_resume("ada")
        outcome = await asyncio.wait_for(run, 60)
    assert outcome.status == "completed", outcome.message
    assert after_first_point(statuses(rec))[:-1] == [
        (
            "paused",
            f"paused at a safe point (drives keep their speeds); asked by ada; next: point 2 of 2: {SECOND} (point 0001)",
            SECOND,
            True,
        ),
        ("running", f"resumed; next: point 2 of 2: {SECOND} (point 0001)", SECOND, True),
        ("running", f"measuring point 2 of 2: {SECOND} (point 0001)", SECOND, False),
        ("running", "every point measured: both drives ramp to zero", None, False),
        ("stopping", "all points completed", None, False),
    ]


async def test_a_pause_for_disk_room_and_its_resume_name_the_next_point(tmp_path, monkeypatch):
    free_bytes, looks = RunStore.free_bytes, []

    def full_before_the_second(self):
        looks.append(None)  # the plan's, the first point's, then the second's: none after a resume
        return 1_000 if len(looks) == 3 else free_bytes(self)

    monkeypatch.setattr(RunStore, "free_bytes", full_before_the_second)
    async with running(tmp_path, MATRIX) as (sim, eng, rec, run):
        await wait_for(lambda: eng.state == "paused", timeout=60, what="paused for room")
        eng.request_resume()
        outcome = await asyncio.wait_for(run, 60)
    assert outcome.status == "completed", outcome.message
    [paused, *after] = after_first_point(statuses(rec))
    assert paused[0] == "paused" and "not enough free disk space" in paused[1], paused
    assert paused[1].endswith(f"then resume the run; next: point 2 of 2: {SECOND} (point 0001)")
    assert paused[1].count("resume") == 1, paused[1]  # the store's advice, said once
    assert paused[2:] == (SECOND, True)
    assert after[:2] == [
        (
            "running",
            f"resumed: there is room for the next point; next: point 2 of 2: {SECOND} (point 0001)",
            SECOND,
            True,
        ),
        ("running", f"measuring point 2 of 2: {SECOND} (point 0001)", SECOND, False),
    ]
    assert not [s for s in after_first_point(statuses(rec)) if FIRST in s[1] or s[2] == FIRST]  # the point done: never


async def test_a_pause_before_the_first_point_names_it(tmp_path, monkeypatch):
    free_bytes, looks = RunStore.free_bytes, []

    def full_before_the_first(self):
        looks.append(None)
        return 1_000 if len(looks) == 2 else free_bytes(self)

    monkeypatch.setattr(RunStore, "free_bytes", full_before_the_first)
    async with running(tmp_path, MATRIX) as (sim, eng, rec, run):
        await wait_for(lambda: eng.state == "paused", timeout=60, what="paused for room")
        [*_, paused] = statuses(rec)
        assert paused[1].endswith(f"; next: point 1 of 2: {FIRST} (point 0000)") and paused[2:] == (FIRST, True)
        eng.request_abort()
        outcome = await asyncio.wait_for(run, 30)
    assert outcome.status == "aborted", outcome.message
    stopping = [s for s in statuses(rec) if s[0] == "stopping"]
    assert stopping and all(s[2] is None for s in stopping)  # no point under way: none named
