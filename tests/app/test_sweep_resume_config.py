"""`sweep --resume --config FILE`: the remaining points are measured as the first ones were, with
the rig configuration and calibration record the run stored. A configuration given again may
change only where the devices are and the planning times ([transports], [estimates],
[changeover]); any other difference, the active calibration record among them, is refused (exit 2)
before anything is started, and the run is left as it was for a resume without --config."""

from __future__ import annotations

import shutil

import pytest

from orbitrig.store.reader import read_run

from support.store_checks import small_matrix
from support.rig_configs import lab_record_config, loads_record
from support.cli_helpers import orbitrig, orbitrig_cmd
from support.sweep_helpers import stop_after_first_point

pytestmark = pytest.mark.timeout(240)


@pytest.fixture(scope="module")
def stopped(tmp_path_factory):
    """A 2-point --sim run stopped by SIGTERM once its first point is complete (exit 3), made once:
    each test resumes a copy of it (`_stopped_run`); nobody writes to this one."""
    folder = tmp_path_factory.mktemp("stopped")
    (folder / "m.toml").write_text(small_matrix("resume", 8, spin_rpm=(1000.0, 2000.0)))
    out = folder / "run"
    cmd = orbitrig_cmd("sweep", "--sim", "--matrix", str(folder / "m.toml"), "--out", str(out))
    stop_after_first_point([*cmd, "--speedup", "10", "--no-draw-figures"], out)
    return out


def _stopped_run(stopped, tmp_path):
    """The test's own copy of the `stopped` run (a run directory holds no path of its own)."""
    return shutil.copytree(stopped, tmp_path / "run")


def _config(tmp_path, record: str | None = None, estimates_s: float | None = None):
    """A copy of the rig configuration the run was started with (the tests' lab: ORBITRIG_HOME)
    and its records; `record`: a new active record's text; `estimates_s`: another store_s
    estimate (a planning time)."""
    edits = {"store_s": f"store_s = {estimates_s}"} if estimates_s is not None else None
    return lab_record_config(tmp_path / "cfg", record, edits)


def _resume(out, *extra):
    return orbitrig(
        "sweep", "--sim", "--resume", "--out", str(out), "--no-draw-figures", *extra, timeout=180, columns=None
    )


def test_another_calibration_record_on_resume_is_refused_and_the_run_resumes_without_it(stopped, tmp_path):
    out = _stopped_run(stopped, tmp_path)
    complete = sorted(p.name for p in read_run(out).points if p.complete)
    p = _resume(out, "--config", str(_config(tmp_path, record=loads_record(0.98))))
    assert p.returncode == 2, p.stderr
    assert "differs from the rig configuration of the run being resumed" in p.stderr
    assert "calibration_record" in p.stderr and "resume without --config" in p.stderr
    assert sorted(q.name for q in read_run(out).points if q.complete) == complete  # nothing measured
    p = _resume(out)
    assert p.returncode == 0, p.stderr
    run = read_run(out)
    assert all(q.complete for q in run.points) and len(run.points) == 2


def test_a_planning_time_may_change_on_resume(stopped, tmp_path):
    out = _stopped_run(stopped, tmp_path)
    p = _resume(out, "--config", str(_config(tmp_path, estimates_s=0.5)))
    assert p.returncode == 0, p.stderr
    assert all(q.complete for q in read_run(out).points)
