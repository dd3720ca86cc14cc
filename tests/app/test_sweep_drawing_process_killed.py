"""`orbitrig sweep --sim` whose report-ahead drawing process (orbitrig.analysis.report_ahead) is
killed mid-run (the kernel's OOM killer: SIGKILL): the sweep goes on, the points after it are not
handed over (the report draws them), and the run completes with both drives ramped to zero (exit
0). A real sweep in a subprocess, the real drawing process killed by a real signal."""

import os
import signal
import time
from pathlib import Path

import pytest

from support.store_checks import small_matrix
from support.sweep_process import SweepProcess

pytestmark = pytest.mark.timeout(120)

SAFE = "spin ACT 0 rpm, fault 0; orbit ACT 0 rpm, fault 0"


def _drawing_processes(pid: int) -> list[int]:
    """The report-ahead drawing processes started by process `pid`."""
    found = []
    for entry in os.listdir("/proc"):
        try:
            args = (Path("/proc") / entry / "cmdline").read_bytes().split(b"\0")
            parent = (Path("/proc") / entry / "stat").read_text().rsplit(")", 1)[1].split()[1]
        except (OSError, ValueError, IndexError):
            continue
        if b"orbitrig.analysis.report_ahead" in args and parent == str(pid):
            found.append(int(entry))
    return found


def test_a_drawing_process_killed_mid_sweep_leaves_the_run_to_complete(tmp_path):
    (tmp_path / "m.toml").write_text(small_matrix("drawn", 10))
    s = SweepProcess(tmp_path / "run", "--matrix", str(tmp_path / "m.toml"))
    try:
        deadline = time.monotonic() + 60
        while not (drawing := _drawing_processes(s.proc.pid)):  # started with the first point complete
            assert s.proc.poll() is None and time.monotonic() < deadline, s.text()[-2000:]
            time.sleep(0.01)
        os.kill(drawing[0], signal.SIGKILL)
        _, err = s.proc.communicate(timeout=90)
    finally:
        s.close()
    assert s.proc.returncode == 0, err[-3000:]
    assert s.status() == "completed"
    log = s.text()
    assert "drives: ramp stop (OFF1); standstill after" in log and SAFE in log, log[-2000:]
    assert "Traceback" not in err
    assert len(list((tmp_path / "run" / "points").glob("*/complete.json"))) == 2
