"""Storage failures at the RunStore level: a full disk is a StorageFullError, leaves no
temporary file and no broken library state (the store keeps working once space is
free); free-space checks and the byte estimates that feed them."""

from __future__ import annotations

import numpy as np
import pytest

from orbitrig import config as cfg
from orbitrig.run.plan import make_plan, operating_points
from orbitrig.store.errors import StorageError, StorageFullError
from orbitrig.store.estimate import block_bytes, plan_bytes, point_bytes, point_room, results_bytes
from orbitrig.store.reader import read_run
from orbitrig.store.writer import BlockRecord, RunStore
from orbitrig.store.status import RunStatus

from support.store_checks import fill, small_matrix

MATRIX = small_matrix("space", revolutions=20)


def _record(block, n=20) -> BlockRecord:
    rng = np.random.default_rng(block.freq)
    return BlockRecord(
        block=block,
        measured_orbit_speed=abs(block.orbit),
        raw_counts=rng.integers(-3000, 3000, (n, 8, 45), dtype=np.int16),
        slots=np.arange(360, dtype=np.int16).reshape(45, 8).T,
        gains=np.ones(8),
        offsets=np.zeros(8),
        mean=rng.standard_normal((8, 45)),
        record_phasors=rng.standard_normal((n, 8)) + 0j,
        phasors=np.ones(8, complex),
        dc=np.zeros(8),
        rms_residual=np.zeros(8),
        coherence=np.ones((2, 4)),
        uncertainty=np.full(8, 1e-3),
        n_records=n,
        stop_reason="count",
    )


def _setup(directory):
    rig = cfg.load_rig()
    m = cfg.matrix_from_text(MATRIX, "space.toml")
    store = RunStore.create(directory, rig_text=rig.text, matrix_text=m.text, matrix_name=m.name, sim=True)
    return rig, m, store


def test_a_refusal_for_too_little_free_space_takes_another_advice(tmp_path):
    """An export advises to export again, whatever full-disk error it met (here the free-space check's)."""
    _, _, store = _setup(tmp_path / "run")
    with pytest.raises(StorageFullError) as err:
        store.check_free_space(1 << 60)
    assert str(err.value).endswith("then resume the run")
    advised = err.value.advising("free space, then export again")
    assert str(advised) == f"{tmp_path / 'run'}: {err.value.problem}: free space, then export again"
    assert "needs" in advised.problem and (advised.needed, advised.free) == (err.value.needed, err.value.free)


def test_full_disk_is_a_storage_full_error_and_the_store_recovers(tiny_disk):
    rig, m, store = _setup(tiny_disk / "run")
    p = operating_points(m, rig)[0]
    store.begin_point(p)
    store.write_block(p.index, _record(p.blocks[0]))
    filler = fill(tiny_disk)
    with pytest.raises(StorageFullError, match="No space left on device.*the disk is full") as err:
        store.write_block(p.index, _record(p.blocks[1]))
    assert err.value.path.endswith("01_fwd.h5") or err.value.path.endswith(".h5.tmp")
    assert not list((tiny_disk / "run").rglob("*.tmp"))  # the torn temporary file is gone
    with pytest.raises(StorageFullError):
        store.set_status(RunStatus.FAILED, "disk full")  # the journal cannot take it either: an error, not a crash
    store.log("still alive")  # run.log is best effort: no exception
    with pytest.raises(StorageFullError, match="needs .* free"):
        store.check_free_space(1)
    filler.unlink()
    store.check_free_space(100_000)
    for b in p.blocks[1:]:  # the same store object and the same HDF5 library keep working
        store.write_block(p.index, _record(b))
    point = read_run(tiny_disk / "run").points[0]
    assert [f.name for f in point.frequencies] == sorted(b.tag for b in p.blocks)


def test_storage_errors_name_the_file(tmp_path):
    with pytest.raises(StorageError, match="does not exist: nothing to resume"):
        RunStore.open_existing(tmp_path)
    (tmp_path / "run.json").write_text("{not json")
    with pytest.raises(StorageError, match=r"run.json: not a readable run header"):
        RunStore.open_existing(tmp_path)
    _, m, store = _setup(tmp_path / "run")
    points = tmp_path / "run" / "points"
    points.rmdir()
    points.write_text("in the way")  # the point directory cannot be created
    with pytest.raises(StorageError, match=r"points/0000: cannot create the point directory"):
        store.begin_point(operating_points(m, cfg.load_rig())[0])


def test_estimates_bound_what_is_written(tmp_path):
    rig, m, store = _setup(tmp_path / "run")
    from orbitrig.run.identification import identify_operating_point

    p = operating_points(m, rig)[0]
    store.begin_point(p)
    recs = [_record(b) for b in p.blocks]
    for r in recs:
        store.write_block(p.index, r)
    store.write_results(p.index, identify_operating_point(p.spin, recs, rig.channel_index, m.models))
    store.complete_point(p.index)
    block = (tmp_path / "run/points/0000/00_fwd.h5").stat().st_size
    assert block <= block_bytes(rig, 20) <= 1.5 * block
    # these records identify without truth: a simulated point's larger results.h5 (truth fits)
    # is measured against the estimate in test_room_before_point
    results = (tmp_path / "run/points/0000/results.h5").stat().st_size
    assert results <= results_bytes(len(p.blocks), 1) <= 8 * results
    point = sum(f.stat().st_size for f in (tmp_path / "run/points/0000").iterdir())
    assert point <= point_bytes(rig, p, 20, 1) <= 3 * point
    assert point_room(rig, p, 20, 1) == 2 * point_bytes(rig, p, 20, 1)  # the pieces and their run.h5 copy
    store.set_status(RunStatus.STOPPED, "one point")
    written = sum(f.stat().st_size for f in (tmp_path / "run").rglob("*") if f.is_file())
    whole = plan_bytes(rig, list(make_plan(m, rig).steps))  # two points: about twice this one's share
    assert 2 * written <= whole <= 6 * written


def test_a_long_wait_keeps_only_the_newest_monitor_rows():
    """Days of CAN and drive rows without a point completed: memory and journal stay bounded."""
    from orbitrig.store.records import MONITOR_ROWS_KEPT, LogBuffer

    buf = LogBuffer()
    for i in range(3 * MONITOR_ROWS_KEPT):
        buf.add("can", (float(i),))
        buf.add("drives", (float(i),))
    buf.add("events", (0.0, "waiting", "manual settings"))
    events, can, drives = buf.take()
    assert len(events) == 1 and len(can) == len(drives) == MONITOR_ROWS_KEPT
    assert can[0] == (2.0 * MONITOR_ROWS_KEPT,) and can[-1] == (3.0 * MONITOR_ROWS_KEPT - 1,)
    buf.add("can", (1e9,))
    buf.put_back(events, can, drives)  # a failed write: they go with the next one, still bounded
    events, can, drives = buf.take()
    assert len(can) == MONITOR_ROWS_KEPT and can[-1] == (1e9,) and can[0] == (2.0 * MONITOR_ROWS_KEPT + 1,)
    assert buf.take() == ([], [], [])


def test_room_for_a_point_counts_what_the_point_before_still_writes(tmp_path, monkeypatch):
    """Before point 1: its pieces and run.h5 copy, plus what point 0 (measured, its results and
    copy still being written in the background) has yet to write; once point 0 is copied into
    run.h5, only point 1."""
    from orbitrig.run.run_dir import no_room

    rig, m, store = _setup(tmp_path / "run")
    plan = make_plan(m, rig)
    p0, p1 = plan.points
    asked = []
    monkeypatch.setattr(RunStore, "check_free_space", lambda self, n: asked.append(n))
    store.begin_point(p0)
    for b in p0.blocks:
        store.write_block(p0.index, _record(b))
    written = sum(f.stat().st_size for f in (tmp_path / "run/points/0000").glob("0*.h5"))  # its blocks
    assert no_room(store, rig, plan, p1) is None
    room0, room1 = point_room(rig, p0, 20, 1), point_room(rig, p1, 20, 1)
    assert asked == [room1 + room0 - written]
    from orbitrig.run.identification import identify_operating_point

    recs = [_record(b) for b in p0.blocks]
    store.write_results(p0.index, identify_operating_point(p0.spin, recs, rig.channel_index, m.models))
    store.complete_point(p0.index)
    assert no_room(store, rig, plan, p1) is None
    assert asked[1:] == [room1]
