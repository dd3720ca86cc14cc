"""What the store's integrity checks read: a point is checked against its commit record (every
file hashed) when the run is resumed, before run.h5 is consolidated and by every reader, but a
commit does not read the points committed before it again (it did: every commit re-hashed the
whole run, O(n^2) over a run, some 100 s of the storage thread's CPU on the paper's matrix).

Real parts: the sweep's own RunStore writing real files and run.h5 (h5py); the hashing is
counted by wrapping the store's own digest (support.store_commits.counting_hashes)."""

from __future__ import annotations

import csv

import h5py

from orbitrig.store.reader import read_run
from orbitrig.store.status import RunStatus
from orbitrig.store.writer import RunStore

from support.store_commits import commit_points, counting_hashes, point_bytes

N = 6


def csv_points(path) -> list[int]:
    """The points of a coefficients.csv, ascending."""
    with open(path, newline="") as fh:
        return sorted({int(row["point"]) for row in csv.DictReader(fh)})


def test_a_commit_hashes_no_point_committed_before_it(tmp_path):
    out, per_commit = tmp_path / "run", []
    with counting_hashes() as hashed:
        commit_points(out, N, on_commit=lambda i, wall, cpu: per_commit.append(hashed.take()))
    own = [point_bytes(out, i) for i in range(N)]
    assert len(per_commit) == N and own[0] > 10_000
    # at most its own files (their digests come from the bytes written): never the points before it
    assert all(n <= own[i] for i, n in enumerate(per_commit)), (per_commit, own)
    assert per_commit[-1] <= per_commit[0], per_commit  # the last commit costs what the first did


def test_the_end_verifies_each_point_once_and_says_one_altered_since_its_commit(tmp_path):
    out = tmp_path / "run"
    store = commit_points(out, 3)
    block = sorted((out / "points" / "0001").glob("0*_fwd.h5"))[0]
    data = bytearray(block.read_bytes())
    data[len(data) // 2] ^= 0xFF  # same size, another digest: a file altered after its commit
    block.write_bytes(bytes(data))
    with counting_hashes() as hashed:
        store.set_status(RunStatus.COMPLETED, "test")  # consolidates run.h5
    # every file of the two intact points once, no file twice (the damaged point: up to its damaged file)
    assert len(hashed.paths) == len(set(hashed.paths)) and block in hashed.paths, hashed.paths
    intact = {f for i in ("0000", "0002") for f in (out / "points" / i).iterdir() if f.name != "complete.json"}
    assert intact <= set(hashed.paths), sorted(intact - set(hashed.paths))
    with h5py.File(out / "run.h5", "r") as f:
        assert [bool(f["points"][p].attrs["complete"]) for p in ("0000", "0001", "0002")] == [True, False, True]
        assert "table" not in f["points/0001"] and "table" in f["points/0002"]
        events = [(e["state"].decode(), e["message"].decode()) for e in f["logs/events"][()]]
    said = f"warning: point 0001 is no longer complete ({block.name} is damaged"
    assert [e for e in events if e[1].startswith(said)] and all(e[0] == "completed" for e in events), events
    store.write_csv()
    store.run_log.flush()
    assert csv_points(out / "coefficients.csv") == [0, 2]
    log = (out / "run.log").read_text()
    assert f"warning: point 0001 is no longer complete ({block.name} is damaged" in log, log
    assert "run.h5 holds it as incomplete, coefficients.csv leaves it out; sweep --resume measures it again" in log
    assert [p.complete for p in read_run(out).points] == [True, False, True]  # a reader checks too


def test_a_resume_verifies_each_point_once(tmp_path):
    out = tmp_path / "run"
    commit_points(out, 4).set_status(RunStatus.STOPPED, "test")
    (out / "run.h5").unlink()
    store = RunStore.open_existing(out)
    store.hold()
    try:
        with counting_hashes() as hashed:
            assert store.prepare_resume() == [0, 1, 2, 3]
            assert store.completed_points() == [0, 1, 2, 3]
            store.write_csv()
        assert hashed.bytes == sum(point_bytes(out, i) for i in range(4))
    finally:
        store.release()


def test_a_resume_with_nothing_to_measure_hashes_each_point_twice_not_four_times(tmp_path):
    """`sweep --resume` of a run cut off before run.h5: the sweep's question whether every point is
    complete and the setting aside share one check under the run's lock, the check before run.h5 is
    the second, and the closing table reads the points that check found (it hashed the run 4 times)."""
    from typer.testing import CliRunner

    from orbitrig.cli import app

    out = tmp_path / "run"
    commit_points(out, 3).release()  # cut off after its last commit: no run.h5
    total = sum(point_bytes(out, i) for i in range(3))
    with counting_hashes() as hashed:
        res = CliRunner().invoke(app, ["sweep", "--resume", "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert "Kxx" in res.stdout and (out / "run.h5").is_file()  # the closing table, run.h5 written
    assert hashed.bytes == 2 * total, (hashed.bytes, total)
    with h5py.File(out / "run.h5", "r") as f:
        assert [bool(f["points"][p].attrs["complete"]) for p in ("0000", "0001", "0002")] == [True] * 3


def test_a_point_altered_during_a_resume_is_still_found_before_run_h5(tmp_path):
    """The one check a resume starts with is not trusted at its end: a point altered since is
    found by the check before run.h5 (stored incomplete, said)."""
    out = tmp_path / "run"
    commit_points(out, 3).set_status(RunStatus.STOPPED, "test")
    store = RunStore.open_existing(out)
    store.hold()
    try:
        assert store.completed_points() == [0, 1, 2]  # the sweep's question: the resume's check
        assert store.prepare_resume() == [0, 1, 2]  # shared
        block = sorted((out / "points" / "0002").glob("0*_fwd.h5"))[0]
        data = bytearray(block.read_bytes())
        data[len(data) // 2] ^= 0xFF  # same size, another digest
        block.write_bytes(bytes(data))
        store.set_status(RunStatus.COMPLETED, "test")
    finally:
        store.release()
    store.run_log.flush()
    assert store.completed_points() == [0, 1]
    with h5py.File(out / "run.h5", "r") as f:
        assert [bool(f["points"][p].attrs["complete"]) for p in ("0000", "0001", "0002")] == [True, True, False]
    assert f"warning: point 0002 is no longer complete ({block.name} is damaged" in (out / "run.log").read_text()
