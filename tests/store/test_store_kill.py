"""Kill `sweep --sim` at exact write points (strace fault injection: SIGKILL at the K-th
call of a write syscall), then `--resume`: every point stored exactly once, every file
whole, and report / reduce / export read the run before and after the resume.

ORBITRIG_KILL_POINTS=all runs the long list of write points (about 30 runs).

Each kill point runs the matrix it needs: one point where the kill comes in point 0000 or
before (the resume measures that point again all the same), two where it comes once point
0001 has begun while point 0000 awaits its results. The report draws one figure kind of the
results and one of the blocks' signals (what it reads of a run does not depend on the kinds).
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
from support.cli_helpers import orbitrig, orbitrig_cmd
from support.store_checks import check_whole, small_matrix
from support.paths import ROOT

ONE = (1000.0,)  # spin speeds, rpm: one point
TWO = (1000.0, 1200.0)  # two points, a short ramp between them
BLOCKS = 6  # 3 ratios x forward, backward
STORAGE_CALLS = "write,pwrite64,fsync,rename,renameat,renameat2"
# (syscalls counted, K, spin speeds): the run is killed at the K-th call of one of them by one
# thread (the main thread writes the run's header and run.log, the storage thread the points'
# files); fsync and rename happen only in the storage's durable steps, write also in logs and output
DEFAULT = [
    ("fsync", 1, ONE),  # the run folder, before run.json: no header, nothing to resume
    ("fsync", 7, ONE),  # the journal's start record: a header, no point begun
    ("rename", 3, ONE),  # point 0000's second block into place: its .tmp left
    ("fsync", 16, ONE),  # the journal after point 0000's fourth block
    ("write", 30, TWO),  # a run.log line: point 0001 begun, point 0000 awaiting its results
    ("rename", 9, TWO),  # point 0001's first block (or point 0000's results.h5) into place
]
LONG = (
    [("fsync", k, TWO) for k in range(1, 36, 2)]
    + [("rename", k, TWO) for k in range(1, 14, 2)]
    + [("write", k, TWO) for k in (5, 15, 25, 35, 45)]
)
CASES = LONG if os.environ.get("ORBITRIG_KILL_POINTS") == "all" else DEFAULT


def _killed_sweep(tmp_path, calls: str, k: int, spin_rpm: tuple[float, ...]):
    matrix = tmp_path / "crash.toml"
    matrix.write_text(small_matrix("crash", revolutions=10, spin_rpm=spin_rpm))
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
@pytest.mark.parametrize("calls, k, spin_rpm", CASES, ids=[f"{c}-{k}" for c, k, _ in CASES])
def test_kill_at_a_write_then_resume_stores_every_point_once(tmp_path, calls, k, spin_rpm):
    out = _killed_sweep(tmp_path, calls, k, spin_rpm)
    runner = CliRunner()
    if (out / "run.json").exists():
        cut = read_run(out)  # whatever resume can read, the readers read
        assert cut.status in ("running", "completed")  # completed: killed while consolidating run.h5
        assert runner.invoke(app, ["export", str(out), "--format", "h5", "--out", str(tmp_path / "cut")]).exit_code == 0
        p = orbitrig("sweep", "--sim", "--resume", str(out), timeout=120, columns=None)
        assert p.returncode == 0, p.stdout + p.stderr
        aside = sorted(x.name for x in (out / "aside").iterdir()) if (out / "aside").exists() else []
        for name in aside:  # what was set aside is named on the terminal and in run.log
            assert (
                f"set aside as aside/{name}" in p.stderr
                and f"set aside as aside/{name}" in (out / "run.log").read_text()
            )
    else:  # killed before the run's header was durable: there is no run to resume
        p = orbitrig("sweep", "--sim", "--resume", str(out), timeout=60, columns=None)
        assert p.returncode == 2 and "nothing to resume" in p.stderr, p.stderr
        p = orbitrig(
            "sweep", "--sim", "--matrix", str(tmp_path / "crash.toml"), "--out", str(out), timeout=120, columns=None
        )
        assert p.returncode == 0, p.stdout + p.stderr
    check_whole(out, list(range(len(spin_rpm))), BLOCKS)
    assert read_run(out).status == "completed"
    r = runner.invoke(app, ["reduce", str(out), "--model", "kc8"])
    assert r.exit_code == 0, r.output
    r = runner.invoke(app, ["report", str(out), "--point", "0", "--figures", "coefficients,signals"])
    assert r.exit_code == 0, r.output
