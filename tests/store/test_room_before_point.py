"""Room for the next point on a real small file system: the run pauses before a point that
does not fit (its pieces, their copy into run.h5, and what the point before it still
writes in the background), never fills the disk in the middle of one; a pause for room that
nobody answers ends the run stopped (exit 3), with run.h5 consolidated when it fits and the
points kept when it does not."""

from __future__ import annotations

import os
import subprocess

import pytest

from orbitrig import config as cfg
from orbitrig.run.plan import make_plan
from orbitrig.run.run_dir import record_end
from orbitrig.run.states import COMPLETED, FAILED, STOPPED
from orbitrig.store.durable import write_atomic
from orbitrig.store.errors import StorageError
from orbitrig.store.estimate import block_bytes, point_room, results_bytes
from orbitrig.store.journal import read_journal
from orbitrig.store.reader import read_run
from orbitrig.store.status import RunStatus
from orbitrig.store.writer import RunStore

from support.paths import ROOT
from support.cli_helpers import orbitrig
from support.small_disk import mounted_tmpfs

pytestmark = pytest.mark.timeout(240)

# four blocks (2 ratios x 2 directions) of 10 revolutions, one model: about 290 kB of pieces
MATRIX = """
name = "room"
revolutions = 10
[operating]
spin_rpm = [1000.0]
recess_pressure_mpa = [0.4826]
pressure_ratio = [0.4]
static_eccentricity = [0.15, 0.0]
dynamic_eccentricity = [0.096]
[orbit]
ratios = [0.5, 0.9]
directions = ["forward", "backward"]
[[models]]
model = "kc8"
"""


@pytest.fixture
def disk(tmp_path):
    """A 4 MB tmpfs; unmounted afterwards."""
    with mounted_tmpfs(tmp_path / "disk", "4m") as mnt:
        yield mnt


def _leave_free(mnt, n_bytes: int) -> int:
    st = os.statvfs(mnt)
    (mnt / "filler").write_bytes(b"\0" * (st.f_bavail * st.f_frsize - n_bytes))
    st = os.statvfs(mnt)
    return st.f_bavail * st.f_frsize


def test_the_run_pauses_before_a_point_that_does_not_fit_and_stops_unanswered(disk, tmp_path):
    matrix, rig_file = tmp_path / "room.toml", tmp_path / "rig.toml"
    matrix.write_text(MATRIX)
    text = (ROOT / "config" / "rig.toml").read_text()
    assert "unanswered_pause_s = 60.0" in text
    rig_file.write_text(text.replace("unanswered_pause_s = 60.0", "unanswered_pause_s = 2.0"))
    rig = cfg.load_rig(rig_file)
    plan = make_plan(cfg.load_matrix(matrix), rig)
    room = point_room(rig, plan.points[0], 10, 1)
    # room for the first point, not for the second beside the first's results and run.h5 copy
    free = _leave_free(disk, room + 150_000)
    out = disk / "run"
    r = orbitrig(
        "sweep",
        "--sim",
        "--no-draw-figures",
        "--speedup",
        "10",
        "--config",
        str(rig_file),
        "--matrix",
        str(matrix),
        "--out",
        str(out),
        timeout=200,
        columns=None,
    )
    log = (out / "run.log").read_text()
    assert r.returncode == 3, r.stdout + r.stderr + log
    assert "No space left" not in log + r.stderr, log
    assert "paused: not enough free disk space" in log, log
    second = "w1000rpm_pr0.4826MPa_b0.4_es0_ed0.096"  # named as the next point, never begun
    assert f"next: point 2 of 2: {second} (point 0001)" in log and f"point 0001 {second}: begin" not in log, log
    run = read_run(out)
    assert run.status == "stopped" and "nobody can answer" in run.status_message, run.status_message
    assert [p.complete for p in run.points] == [True]
    assert (out / "run.h5").exists() and not list(out.glob("*.tmp"))
    # the estimates bound what a simulated point wrote (truth fits included)
    point = out / "points" / "0000"
    assert (point / "results.h5").stat().st_size <= results_bytes(4, 1)
    assert max(f.stat().st_size for f in point.glob("0*.h5")) <= block_bytes(rig, 10)
    pieces = sum(f.stat().st_size for f in point.iterdir())
    used = free - os.statvfs(disk).f_bavail * os.statvfs(disk).f_frsize  # pieces, run.h5, logs
    assert pieces + 250_000 < used <= room + 100_000, (pieces, used, room)


def test_a_stopped_run_whose_run_h5_does_not_fit_stays_stopped(disk):
    """The status is recorded, run.h5 is not (too little room): the run stays stopped, not failed
    (its pieces hold the complete points; a resume consolidates run.h5) and says so; a completed
    run without its run.h5 still fails."""
    rig = cfg.load_rig()
    mat = cfg.matrix_from_text(MATRIX, "room.toml")
    for status in (STOPPED, COMPLETED):
        out = disk / str(status)
        store = RunStore.create(out, rig_text=rig.text, matrix_text=mat.text, matrix_name=mat.name, sim=True)
        _leave_free(disk, 24_576)  # the status line fits, run.h5 (about 64 kB and more) does not
        failures: list[str] = []
        ended = record_end(store, "r1", status, "as asked", lambda what, err, f=failures: f.append(what))
        (disk / "filler").unlink()
        j = read_journal(store.layout.journal)
        assert not (out / "run.h5").exists() and not list(out.glob("*.tmp"))
        if status == COMPLETED:
            assert ended[0] == FAILED and failures == ["write the run status and run.h5"]
            assert j.status == RunStatus.FAILED
            continue
        assert ended[0] == STOPPED and failures == [], ended
        assert ended[1].startswith(f"as asked; run.h5 not written ({out}: needs "), ended[1]
        assert ended[1].endswith("; the points are kept: resume the run once there is room")
        assert j.status == RunStatus.STOPPED and j.status_message == ended[1]
        assert read_run(out).status == "stopped"


def test_a_read_only_directory_cannot_create_rather_than_remove_a_leftover(disk):
    """No leftover NAME.tmp: the error is that the file cannot be created (read-only), not that
    a leftover cannot be removed; a real leftover on a read-only disk is still named as such."""
    (disk / "old.json.tmp").write_bytes(b"a kill's leftover")
    subprocess.run(["mount", "-o", "remount,ro", str(disk)], check=True)
    with pytest.raises(StorageError) as err:
        write_atomic(disk / "new.json", b"{}")
    assert str(err.value) == f"{disk}/new.json.tmp: cannot create: OSError: Read-only file system"
    with pytest.raises(StorageError, match=r"old.json.tmp: cannot remove the leftover temporary file: .*Read-only"):
        write_atomic(disk / "old.json", b"{}")
    with pytest.raises(StorageError, match=r"run/points: cannot create the run directory: .*Read-only file system"):
        RunStore.create(disk / "run", rig_text="", matrix_text="", matrix_name="m", sim=True)
