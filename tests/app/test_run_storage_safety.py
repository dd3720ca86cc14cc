"""Safety before storage: a storage failure stops the drives first; no room pauses the run.

A full disk cannot be produced here without mounting a small file system, so
the store's failure is injected (RunStore.write_block raising StorageFullError,
as the store raises it when the disk is full) and the free space the store
reads is replaced; everything else is the real engine, store and simulator.
"""

import asyncio
import threading
import time

import pytest

from orbitrig import config as cfg
from orbitrig.cli.simulated_rig import simulated_access
from orbitrig.run import background
from orbitrig.run.background import Background, to_the_end
from orbitrig.run.engine import RunEngine, StatusEvent
from orbitrig.run.events import RunFailed
from orbitrig.run.plan import make_plan
from orbitrig.store.estimate import plan_bytes, point_room
from orbitrig.store.writer import RunStore, StorageFullError
from sim.rig import SimRig
from support.loop_beats import LoopBeats
from support.sweep_helpers import SPEEDUP, small_matrix, wait_for

pytestmark = pytest.mark.timeout(120)


def _at_rest(sim) -> bool:
    return all(abs(s) < 1.0 for s in sim.speeds)


async def test_no_write_follows_a_failed_one():
    """Writes queued behind a failing one (blocks measured while it ran) never reach the disk:
    the lock passes on as the failure is raised, before the task's done callback records it."""
    failures: list[BaseException] = []
    bg = Background({}, on_failure=failures.append)
    release, written = threading.Event(), []

    def block(tag: str) -> None:
        if tag == "02_fwd":
            release.wait(5)
            raise StorageFullError("run", "no space left on device (disk full)")
        written.append(tag)

    for tag in ("03_fwd", "02_fwd", "01_fwd", "00_fwd"):
        bg.spawn(bg.write(block, tag), f"store {tag}")
    await asyncio.sleep(0.05)  # 02_fwd in the storage thread, 01_fwd and 00_fwd queued behind it
    release.set()
    await bg.settle()
    assert written == ["03_fwd"]
    assert len(failures) == 1 and isinstance(failures[0], StorageFullError)
    assert isinstance(bg.error, StorageFullError)
    with pytest.raises(RunFailed, match="storage failed: StorageFullError"):
        bg.check()


async def test_a_cancelled_wait_for_the_storage_thread_waits_for_its_end():
    """The run's end record is never cut off: a cancellation is raised once it has ended."""
    ended = threading.Event()

    def record():
        time.sleep(0.3)
        ended.set()

    task = asyncio.create_task(to_the_end(record))
    await asyncio.sleep(0.05)
    task.cancel()
    with pytest.raises(asyncio.CancelledError):
        await task
    assert ended.is_set()


async def test_storage_failure_stops_the_drives_before_recording(tmp_path, monkeypatch):
    write_block, writes, at_status = RunStore.write_block, [], []

    def failing_write_block(self, point, rec):
        writes.append(rec.block.tag)
        if len(writes) == 3:
            raise StorageFullError(self.dir, "no space left on device (disk full)")
        return write_block(self, point, rec)

    set_status = RunStore.set_status

    def watched_set_status(self, status, message=""):
        at_status.append((status, _at_rest(sim)))
        return set_status(self, status, message)

    monkeypatch.setattr(RunStore, "write_block", failing_write_block)
    monkeypatch.setattr(RunStore, "set_status", watched_set_status)
    async with SimRig(speedup=SPEEDUP, adc_pty=False) as sim:
        eng = RunEngine(cfg.load_rig(), out_dir=tmp_path / "run", access=simulated_access(sim), confirm_mode="auto")
        outcome = await eng.run(small_matrix())
        assert _at_rest(sim)
    assert outcome.status == "failed" and eng.state == "faulted"
    assert outcome.message.startswith("storage failed: StorageFullError:") and "disk full" in outcome.message
    assert at_status == [("failed", True)]  # the drives were at rest before the status was recorded
    assert len(writes) == 3  # the run ended at the failed write: no block after it
    assert RunStore.open_existing(tmp_path / "run").stored_configs()  # the run file is still readable


async def test_the_runs_end_is_recorded_off_the_loop(tmp_path, monkeypatch):
    """run.h5 is consolidated and synced at the run's end (half a second for the paper matrix
    on an idle disk, longer on a slow one) in the storage thread: the loop, which in the
    service also answers MQTT, keeps running meanwhile."""
    set_status, window = RunStore.set_status, []

    def slow_set_status(self, status, message=""):
        start = time.monotonic()
        time.sleep(0.6)  # a slow disk
        result = set_status(self, status, message)
        window.append((start, time.monotonic(), threading.current_thread().name))
        return result

    monkeypatch.setattr(RunStore, "set_status", slow_set_status)
    async with SimRig(speedup=SPEEDUP, adc_pty=False) as sim, LoopBeats() as beats:
        eng = RunEngine(cfg.load_rig(), out_dir=tmp_path / "run", access=simulated_access(sim), confirm_mode="auto")
        outcome = await eng.run(small_matrix())
    assert outcome.status == "completed", outcome.message
    [(start, end, thread)] = window
    assert thread.startswith("orbitrig-storage")
    assert beats.within(start, end) >= 5  # a blocked loop: none
    assert RunStore.open_existing(tmp_path / "run").completed_points() == [0]


async def test_no_room_for_the_next_point_pauses_until_resumed(tmp_path, monkeypatch):
    full = {"on": True}
    asked = []
    check = RunStore.check_free_space

    def watched_check(self, n_bytes):
        asked.append(n_bytes)
        return check(self, n_bytes)

    monkeypatch.setattr(RunStore, "free_bytes", lambda self: 1_000 if full["on"] else 10**15)
    monkeypatch.setattr(RunStore, "check_free_space", watched_check)
    rig, matrix = cfg.load_rig(), small_matrix()
    async with SimRig(speedup=SPEEDUP, adc_pty=False) as sim:
        eng = RunEngine(rig, out_dir=tmp_path / "run", access=simulated_access(sim), confirm_mode="auto")
        events = []
        eng.subscribe(events.append)
        run = asyncio.create_task(eng.run(matrix))
        await wait_for(lambda: eng.state == "paused", what="paused for room")
        assert "not enough free disk space" in eng.message and "resume" in eng.message
        assert _at_rest(sim)  # held before the point: nothing turned
        eng.request_resume()  # still no room: stays paused
        await asyncio.sleep(0.2)
        assert eng.state == "paused" and not run.done()
        full["on"] = False
        eng.request_resume()
        outcome = await run
    assert outcome.status == "completed", outcome.message
    assert outcome.completed_points == [0]
    states = [e.state for e in events if isinstance(e, StatusEvent)]
    assert states[:3] == ["running", "paused", "running"]
    plan = make_plan(matrix, rig)
    # asked for the whole plan before the run, then for the point (again after each resume)
    assert asked[0] == plan_bytes(rig, list(plan.steps))
    assert asked[1:4] == [point_room(rig, plan.points[0], 10, len(matrix.models))] * 3  # pieces and run.h5 copy


async def test_the_free_space_check_before_a_point_is_off_the_loop(tmp_path, monkeypatch):
    """The check before each point reads the disk (statvfs), which a hung network share holds
    (injected: a real file system does not hang here); the loop, polling the drives that turn
    from the point before, keeps running meanwhile."""
    free_bytes, window = RunStore.free_bytes, []

    def slow_free_bytes(self):
        start = time.monotonic()
        if not threading.current_thread().name.startswith("orbitrig-storage"):  # not run.h5's at the end
            time.sleep(1.0)
            window.append((start, time.monotonic()))
        return free_bytes(self)

    monkeypatch.setattr(RunStore, "free_bytes", slow_free_bytes)
    async with SimRig(speedup=SPEEDUP, adc_pty=False) as sim, LoopBeats() as beats:
        eng = RunEngine(cfg.load_rig(), out_dir=tmp_path / "run", access=simulated_access(sim), confirm_mode="auto")
        outcome = await eng.run(small_matrix(spin_rpm=[1000.0, 2000.0]))
    assert outcome.status == "completed", outcome.message
    assert len(window) == 3  # the whole plan's before the drives move, then before each point
    for start, end in window[1:]:
        # a loop held by the check: none in its 1 s; a loop starved with both cores busy still beats
        # (9 of the 100 at 10 ms seen with the simulator in this process at a load of 20)
        assert beats.within(start, end) >= 3


async def test_a_long_wait_for_the_points_before_is_said(monkeypatch):
    """The next point waits for the points still identified and stored (bounded memory); a disk
    that stalls them makes the wait long, and the run's events say so every BACKLOG_NOTE_S."""
    monkeypatch.setattr(background, "BACKLOG_NOTE_S", 0.1)
    bg, notes, release = Background({}), [], asyncio.Event()
    bg.spawn_point(release.wait(), "complete point 0000")
    bg.spawn_point(release.wait(), "complete point 0001")
    waiting = asyncio.create_task(bg.wait_for_points(note=notes.append))
    await asyncio.sleep(0.35)
    assert not waiting.done()
    assert 2 <= len(notes) <= 3 and all(n.startswith("waiting for complete point 0000 ") for n in notes), notes
    assert notes[-1].split(" for ")[2].startswith("0 s")  # how long, in s
    release.set()
    await waiting
    assert bg.timing["backlog"] >= 0.35
