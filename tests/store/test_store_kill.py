"""Kill `sweep --sim` at exact write points (strace fault injection: SIGKILL at the K-th
call of a write syscall), then `--resume`: every point stored exactly once, every file
whole, and report / reduce / export read the run before and after the resume.

ORBITRIG_KILL_POINTS=all runs the long list of write points (about 30 runs).
"""

from __future__ import annotations

import os
import signal
import subprocess

import pytest
from typer.testing import CliRunner

from orbitrig.cli import app
from orbitrig.store.reader import read_run

from support.rig_configs import patient_rig_config
from support.store_checks import check_whole, orbitrig_cmd, small_matrix
from support.paths import ROOT

MATRIX = small_matrix("crash", revolutions=10)
BLOCKS = 6  # 3 ratios x forward, backward
STORAGE_CALLS = "write,pwrite64,fsync,rename,renameat,renameat2"
# (syscalls counted, K): the run is killed at the K-th call of one of them by one thread;
# fsync and rename happen only in the storage's durable steps, write also in logs and output
DEFAULT = [("fsync", 1), ("rename", 3), ("fsync", 7), ("fsync", 16), ("write", 30), ("rename", 9)]
LONG = (
    [("fsync", k) for k in range(1, 36, 2)]
    + [("rename", k) for k in range(1, 14, 2)]
    + [("write", k) for k in (5, 15, 25, 35, 45)]
)
CASES = LONG if os.environ.get("ORBITRIG_KILL_POINTS") == "all" else DEFAULT


def _killed_sweep(tmp_path, calls: str, k: int):
    matrix = tmp_path / "crash.toml"
    matrix.write_text(MATRIX)
    out = tmp_path / "run"
    cmd = [
        "strace",
        "-f",
        "-qq",
        "-o",
        "/dev/null",
        "-e",
        f"trace={STORAGE_CALLS}",
        "-e",
        f"inject={calls}:signal=KILL:when={k}",
        *orbitrig_cmd(
            "sweep", "--sim", "--config", str(patient_rig_config(tmp_path)), "--matrix", str(matrix), "--out", str(out)
        ),
    ]
    p = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert p.returncode in (-signal.SIGKILL, 128 + signal.SIGKILL), f"not killed at {calls} #{k}:\n{p.stderr}"
    return out


@pytest.mark.timeout(240)
@pytest.mark.parametrize("calls, k", CASES)
def test_kill_at_a_write_then_resume_stores_every_point_once(tmp_path, calls, k):
    out = _killed_sweep(tmp_path, calls, k)
    runner = CliRunner()
    if (out / "run.json").exists():
        cut = read_run(out)  # whatever resume can read, the readers read
        assert cut.status in ("running", "completed")  # completed: killed while consolidating run.h5
        assert runner.invoke(app, ["export", str(out), "--format", "h5", "--out", str(tmp_path / "cut")]).exit_code == 0
        p = subprocess.run(
            orbitrig_cmd("sweep", "--sim", "--resume", str(out)), cwd=ROOT, capture_output=True, text=True, timeout=120
        )
        assert p.returncode == 0, p.stdout + p.stderr
        aside = sorted(x.name for x in (out / "aside").iterdir()) if (out / "aside").exists() else []
        for name in aside:  # what was set aside is named on the terminal and in run.log
            assert (
                f"set aside as aside/{name}" in p.stderr
                and f"set aside as aside/{name}" in (out / "run.log").read_text()
            )
    else:  # killed before the run's header was durable: there is no run to resume
        p = subprocess.run(
            orbitrig_cmd("sweep", "--sim", "--resume", str(out)), cwd=ROOT, capture_output=True, text=True, timeout=60
        )
        assert p.returncode == 2 and "nothing to resume" in p.stderr, p.stderr
        p = subprocess.run(
            orbitrig_cmd("sweep", "--sim", "--matrix", str(tmp_path / "crash.toml"), "--out", str(out)),
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert p.returncode == 0, p.stdout + p.stderr
    check_whole(out, [0, 1], BLOCKS)
    assert read_run(out).status == "completed"
    r = runner.invoke(app, ["reduce", str(out), "--model", "kc8"])
    assert r.exit_code == 0, r.output
    r = runner.invoke(app, ["report", str(out), "--point", "0"])
    assert r.exit_code == 0, r.output
