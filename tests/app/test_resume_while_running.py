"""A `sweep --resume` of a run that another process is still running is refused (exit 2, naming
the run and why) before it moves or writes anything, and that run goes on undisturbed to its
end. Without the hold the resume set aside the point being measured (the running sweep's next
write into it failed) and removed the run.h5.tmp it was streaming; on the rig two processes
would have commanded the drives. A run whose process was killed holds nothing (the kill tests
resume such runs).

Real parts: two `orbitrig sweep` processes on the simulator, the run folder on disk."""

from __future__ import annotations

import subprocess
import time

import h5py
import pytest

from support.cli_helpers import orbitrig, orbitrig_started, reaped
from support.store_checks import small_matrix

pytestmark = pytest.mark.timeout(240)


def test_a_resume_of_a_run_under_way_is_refused_and_the_run_goes_on(tmp_path):
    matrix, out = tmp_path / "five.toml", tmp_path / "run"
    matrix.write_text(small_matrix("five", 30, spin_rpm=(1000.0, 1100.0, 1200.0, 1300.0, 1400.0)))
    args = ("sweep", "--sim", "--matrix", str(matrix), "--out", str(out), "--no-draw-figures")
    with reaped(orbitrig_started(*args, stdin=None, stdout=subprocess.DEVNULL)) as run:
        deadline = time.monotonic() + 90
        while not (out / "points" / "0000" / "complete.json").exists():
            assert run.poll() is None, run.communicate()[1]
            assert time.monotonic() < deadline, "point 0000 never completed"
            time.sleep(0.01)
        before = sorted(p.name for p in (out / "points").iterdir())
        resumed = orbitrig("sweep", "--sim", "--resume", str(out), "--speedup", "50")
        assert resumed.returncode == 2, (run.poll(), resumed.stderr)  # run.poll(): None, the run goes on
        said = f"error: {out}: in use by another orbitrig process (the run or a resume of it): wait"
        assert said in resumed.stderr and "Traceback" not in resumed.stderr, resumed.stderr
        assert "simulator scenario of the run" not in resumed.stderr  # nothing started
        assert not (out / "aside").exists() and sorted(p.name for p in (out / "points").iterdir()) >= before
        assert run.wait(120) == 0, run.communicate()[1]
    assert not (out / "aside").exists()
    with h5py.File(out / "run.h5", "r") as f:
        assert f.attrs["status"] == "completed" and sorted(f["points"]) == ["0000", "0001", "0002", "0003", "0004"]
        assert all(bool(f["points"][p].attrs["complete"]) for p in f["points"])
    again = orbitrig("sweep", "--sim", "--resume", str(out))  # the run's process has ended: held no more
    assert again.returncode == 0 and "nothing left to do" in again.stdout, again.stderr
