"""Safety before storage: a storage failure stops the drives first; no room pauses the run.

A full disk cannot be produced here without mounting a small file system, so
the store's failure is injected (RunStore.write_block raising StorageError,
as the store raises it for every write failure) and the free-space answer is
replaced; everything else is the real engine on the real simulator.
"""

import asyncio

import pytest

from orbitrig import config as cfg
from orbitrig.cli.simulated_rig import simulated_access
from orbitrig.run import engine as engine_module
from orbitrig.run.engine import RunEngine, StatusEvent
from orbitrig.run.storage_room import MARGIN_BYTES, point_bytes, room_problem
from orbitrig.store.writer import RunStore, StorageError
from sim.rig import SimRig
from sweep_helpers import SPEEDUP, small_matrix, wait_for

pytestmark = pytest.mark.timeout(120)


def _at_rest(sim) -> bool:
    return all(abs(s) < 1.0 for s in sim.speeds)


async def test_storage_failure_stops_the_drives_before_recording(tmp_path, monkeypatch):
    write_block, writes, at_status = RunStore.write_block, [], []

    def failing_write_block(self, point, rec):
        writes.append(rec.block.tag)
        if len(writes) == 3:
            raise StorageError(f"{self.path}: no space left on device (disk full)")
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
    assert outcome.message.startswith("storage failed: StorageError:") and "disk full" in outcome.message
    assert at_status == [("failed", True)]  # the drives were at rest before the status was recorded
    assert len(writes) == 3  # the run ended at the failed write: no block after it
    assert RunStore.open_existing(tmp_path / "run").stored_configs()  # the run file is still readable


async def test_no_room_for_the_next_point_pauses_until_resumed(tmp_path, monkeypatch):
    full = {"on": True}
    asked = []

    def fake_room(directory, n_bytes):
        asked.append(n_bytes)
        return "not enough free disk space in the test: 1.0 MB free" if full["on"] else None

    monkeypatch.setattr(engine_module, "room_problem", fake_room)
    async with SimRig(speedup=SPEEDUP, adc_pty=False) as sim:
        eng = RunEngine(cfg.load_rig(), out_dir=tmp_path / "run", access=simulated_access(sim), confirm_mode="auto")
        events = []
        eng.subscribe(events.append)
        run = asyncio.create_task(eng.run(small_matrix()))
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
    one_point = point_bytes(10, 10, 8, 360)
    assert asked[0] == one_point  # the whole plan (one point) before the run, then before the point
    assert all(n == one_point for n in asked)


def test_room_problem_reads_the_real_disk(tmp_path):
    assert room_problem(tmp_path, 0) is None
    why = room_problem(tmp_path, 10**18)
    assert why is not None and str(tmp_path) in why and "MB free" in why
    # a 50-revolution block of 8 channels x 360 slots holds 288 kB of raw counts
    assert point_bytes(1, 50, 8, 360) > 50 * 8 * 360 * 2
    assert MARGIN_BYTES > 0
