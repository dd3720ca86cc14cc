"""`sweep --resume --config FILE`: the remaining points are measured as the first ones were, with
the rig configuration and calibration record the run stored. A configuration given again may
change only where the devices are and the planning times ([transports], [estimates],
[changeover]); any other difference, the active calibration record among them, is refused (exit 2)
before anything is started, and the run is left as it was for a resume without --config."""

from __future__ import annotations

import shutil
import signal
import subprocess
import time

import pytest

from orbitrig.config import default_rig_path
from orbitrig.store.reader import read_run

from support.paths import ROOT
from support.store_checks import small_matrix
from support.sweep_helpers import orbitrig_cmd

pytestmark = pytest.mark.timeout(240)

#: a record that corrects the strain gauges (gain 0.98): another calibration than the stored one
LOADS_RECORD = """date = "2026-12-01T00:00:00+00:00"
operator = "test"
rig = "double-spool rig"
step = "loads"
previous = "2026-11-26T214732Z-initial"
[reference]
id = "dead-weights"
uncertainty_pct = 0.1
[loads.strain]
gain = [[0.98, 0.0], [0.0, 0.98]]
gain_u = [[0.001, 0.0], [0.0, 0.001]]
"""


def _stopped_run(tmp_path):
    """A 2-point --sim run stopped by SIGTERM once its first point is complete (exit 3)."""
    (tmp_path / "m.toml").write_text(small_matrix("resume", 8, spin_rpm=(1000.0, 2000.0)))
    out = tmp_path / "run"
    cmd = orbitrig_cmd("sweep", "--sim", "--matrix", str(tmp_path / "m.toml"), "--out", str(out))
    proc = subprocess.Popen([*cmd, "--speedup", "10", "--no-draw-figures"], cwd=ROOT, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 120
        while not list(out.glob("points/*/complete.json")):
            assert proc.poll() is None and time.monotonic() < deadline, "no point completed"
            time.sleep(0.05)
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(60) == 3
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return out


def _config(tmp_path, record: str | None = None, estimates_s: float | None = None):
    """A copy of the rig configuration the run was started with (the tests' lab: ORBITRIG_HOME)
    and its records; `record`: a new active record's text; `estimates_s`: another store_s
    estimate (a planning time)."""
    started = default_rig_path()
    folder = tmp_path / "cfg"
    shutil.copytree(started.parent / "calibration", folder / "calibration")
    text = started.read_text()
    if record is not None:
        (folder / "calibration" / "2026-12-01T000000Z-loads.toml").write_text(record)
        old = next(ln for ln in text.splitlines() if ln.startswith("calibration_record"))
        text = text.replace(old, 'calibration_record = "2026-12-01T000000Z-loads"')
    if estimates_s is not None:
        old = next(ln for ln in text.splitlines() if ln.startswith("store_s"))
        text = text.replace(old, f"store_s = {estimates_s}")
    (folder / "rig.toml").write_text(text)
    return folder / "rig.toml"


def _resume(out, *extra):
    return subprocess.run(
        orbitrig_cmd("sweep", "--sim", "--resume", "--out", str(out), "--no-draw-figures", *extra),
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=180,
    )


def test_another_calibration_record_on_resume_is_refused_and_the_run_resumes_without_it(tmp_path):
    out = _stopped_run(tmp_path)
    complete = sorted(p.name for p in read_run(out).points if p.complete)
    p = _resume(out, "--config", str(_config(tmp_path, record=LOADS_RECORD)))
    assert p.returncode == 2, p.stderr
    assert "differs from the rig configuration of the run being resumed" in p.stderr
    assert "calibration_record" in p.stderr and "resume without --config" in p.stderr
    assert sorted(q.name for q in read_run(out).points if q.complete) == complete  # nothing measured
    p = _resume(out)
    assert p.returncode == 0, p.stderr
    run = read_run(out)
    assert all(q.complete for q in run.points) and len(run.points) == 2


def test_a_planning_time_may_change_on_resume(tmp_path):
    out = _stopped_run(tmp_path)
    p = _resume(out, "--config", str(_config(tmp_path, estimates_s=0.5)))
    assert p.returncode == 0, p.stderr
    assert all(q.complete for q in read_run(out).points)
