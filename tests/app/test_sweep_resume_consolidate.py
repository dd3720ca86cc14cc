"""`sweep --resume` of a run cut off after its last point was committed, before run.h5 was
consolidated: run.h5 is written from the stored pieces without starting the simulator or the
drives (it started both and ran the run's closing ramp just to consolidate), said, exit 0,
the run recorded completed, and run.h5 holds exactly what the run measured.

Real parts: the `orbitrig` command line (subprocesses) on the simulator; the cut-off folder is
a finished run's, as a kill after the last commit leaves it: no run.h5, a run.h5.tmp left, the
journal ending at the last point's commit record (status running).

The consolidation's progress is said ('run.h5: 40 of 120 points copied (12 s)'), also at the
end of a resume that measured points: it copies the points completed before it (silently)."""

from __future__ import annotations

import json
import shutil
import subprocess

import h5py
import numpy as np
import pytest

from support.cli_helpers import orbitrig
from support.small_disk import mounted_tmpfs
from support.store_checks import small_matrix

pytestmark = pytest.mark.timeout(240)


def _sweep(*args: str) -> subprocess.CompletedProcess[str]:
    return orbitrig("sweep", *args, timeout=180, columns=None)


def _cut_after_last_commit(out) -> None:
    """The folder as a kill after the last point's commit leaves it (before the closing ramp)."""
    (out / "run.h5").unlink()
    (out / "run.h5.tmp").write_bytes(b"\x89HDF\r\n cut off")  # the consolidation under way
    lines = (out / "journal.jsonl").read_text().splitlines()
    last = max(i for i, x in enumerate(lines) if json.loads(x).get("action") == "complete")
    (out / "journal.jsonl").write_text("\n".join(lines[: last + 1]) + "\n")


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A finished two-point run on the simulator (its folder copied by each test that cuts it)."""
    tmp = tmp_path_factory.mktemp("consolidate")
    matrix, out = tmp / "two.toml", tmp / "run"
    matrix.write_text(small_matrix("two", 8))
    first = _sweep("--sim", "--matrix", str(matrix), "--out", str(out), "--speedup", "50", "--no-draw-figures")
    assert first.returncode == 0, first.stderr
    return out


def _points(path) -> dict[str, np.ndarray]:
    """Every dataset under /points of an HDF5 file, by path."""
    found: dict[str, np.ndarray] = {}
    with h5py.File(path, "r") as f:
        f["points"].visititems(
            lambda name, obj: found.update({name: obj[()]}) if isinstance(obj, h5py.Dataset) else None
        )
    return found


def test_a_resume_cut_off_before_run_h5_consolidates_it_without_the_rig(finished, tmp_path):
    out = shutil.copytree(finished, tmp_path / "run")
    measured = _points(out / "run.h5")
    _cut_after_last_commit(out)
    journal_before = (out / "journal.jsonl").read_text()

    again = _sweep("--sim", "--resume", str(out))

    assert again.returncode == 0, again.stderr
    said = f"resume: all 2 points of the run in {out} are complete; its run.h5 is missing: consolidating it"
    assert said in again.stderr and "the simulator and the drives are not started" in again.stderr, again.stderr
    assert "simulator scenario of the run" not in again.stderr  # the simulator was not started
    assert "run.h5: 2 of 2 points copied (" in again.stderr  # the consolidation's progress
    assert "Kxx" in again.stdout  # the closing table of the coefficients, as a completed sweep prints it
    added = [json.loads(x) for x in (out / "journal.jsonl").read_text()[len(journal_before) :].splitlines()]
    assert [x["status"] for x in added if x["k"] == "status"] == ["running", "completed"]
    assert not [x for x in added if x["k"] in ("event", "drive", "can")], added  # no state, no drive touched
    assert not (out / "run.h5.tmp").exists()
    with h5py.File(out / "run.h5", "r") as f:
        assert f.attrs["status"] == "completed"
        assert sorted(f["points"]) == ["0000", "0001"]
        assert [bool(f["points"][p].attrs["complete"]) for p in ("0000", "0001")] == [True, True]
        assert "resumed to consolidate run.h5" in f["logs/commands"]["detail"][-1].decode()
    again_points = _points(out / "run.h5")
    assert again_points.keys() == measured.keys() and len(measured) > 20
    for name, data in measured.items():  # every block and result, as the run measured it
        assert np.array_equal(again_points[name], data, equal_nan=data.dtype.kind == "f"), name
    nothing = _sweep("--sim", "--resume", str(out))  # and now: nothing left to do
    assert nothing.returncode == 0 and "nothing left to do" in nothing.stdout, nothing.stderr


def test_a_resume_that_measures_says_its_copy_of_the_earlier_points(finished, tmp_path):
    out = shutil.copytree(finished, tmp_path / "run")
    (out / "points" / "0001" / "complete.json").unlink()  # cut before point 0001's commit
    again = _sweep("--sim", "--resume", str(out), "--speedup", "50", "--no-draw-figures")
    assert again.returncode == 0, again.stderr
    assert "point 0001 set aside as aside/0001.incomplete.1" in again.stderr
    lines = again.stderr.splitlines()
    copied = [i for i, x in enumerate(lines) if x.startswith("run.h5: 1 of 1 points copied (")]  # point 0000
    closing = [i for i, x in enumerate(lines) if x.startswith("run completed: all points completed")]
    assert len(copied) == 1 and closing and copied[0] < closing[0], again.stderr
    with h5py.File(out / "run.h5", "r") as f:
        assert sorted(f["points"]) == ["0000", "0001"] and f.attrs["status"] == "completed"


def test_a_consolidation_without_room_fails_and_a_resume_with_room_writes_it(finished, tmp_path):
    """No room for run.h5: exit 1, said with what to do, the pieces kept and nothing half
    written; once there is room, the next resume consolidates it (still without the rig)."""
    first_out = shutil.copytree(finished, tmp_path / "first")
    _cut_after_last_commit(first_out)
    used = sum(p.stat().st_size for p in first_out.rglob("*") if p.is_file())
    with mounted_tmpfs(tmp_path / "disk", f"{used // 1024 + 400}k") as disk:
        out = disk / "run"
        shutil.copytree(first_out, out)
        full = _sweep("--sim", "--resume", str(out))
        assert full.returncode == 1, full.stderr
        assert f"{out}: needs " in full.stderr and "free space on this disk" in full.stderr, full.stderr
        assert "then resume the run" in full.stderr and "Traceback" not in full.stderr
        assert not (out / "run.h5").exists() and not (out / "run.h5.tmp").exists()
        assert json.loads((out / "journal.jsonl").read_text().splitlines()[-1])["status"] == "failed"
        subprocess.run(["mount", "-o", "remount,size=8m", str(disk)], check=True)
        again = _sweep("--sim", "--resume", str(out))
        assert again.returncode == 0, again.stderr
        assert "simulator scenario of the run" not in again.stderr and "run.h5: 2 of 2 points copied" in again.stderr
        with h5py.File(out / "run.h5", "r") as f:
            assert f.attrs["status"] == "completed" and sorted(f["points"]) == ["0000", "0001"]


def test_a_rig_run_cut_off_before_run_h5_is_consolidated_with_the_rig_unreachable(finished, tmp_path):
    """A run made on the rig (its header says so), resumed where the rig does not answer (this
    machine): run.h5 is written all the same. It was refused (exit 2: the rig must answer),
    so such a run could not be finished away from the rig."""
    out = shutil.copytree(finished, tmp_path / "run")
    _cut_after_last_commit(out)
    header = json.loads((out / "run.json").read_text())
    header["sim"] = False
    del header["sim_scenario"]
    (out / "run.json").write_text(json.dumps(header, indent=1))
    again = _sweep("--resume", str(out))
    assert again.returncode == 0, again.stderr
    assert "cannot connect" not in again.stderr and "run.h5: 2 of 2 points copied (" in again.stderr
    with h5py.File(out / "run.h5", "r") as f:
        assert f.attrs["status"] == "completed" and not f.attrs["sim"] and sorted(f["points"]) == ["0000", "0001"]
