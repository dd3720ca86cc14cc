"""`sweep --resume` opens the run it continues once: run.json is read by one owner (the run's
store, opened at the start) and handed on to the configurations, the point order, the
scenario, the complete points and the engine. It was opened three times by a resume with
nothing left (configurations, plan order, nothing-left check) and four by its dry run
(configurations, plan order, scenario, complete points).

Real parts: the `orbitrig` command line on the simulator, its file opens traced by strace."""

from __future__ import annotations

import shutil
import subprocess

import pytest

from support.cli_helpers import orbitrig, orbitrig_cmd
from support.paths import ROOT
from support.store_checks import small_matrix

pytestmark = [
    pytest.mark.timeout(240),
    pytest.mark.skipif(shutil.which("strace") is None, reason="needs strace"),
]


def _opens_of_header(tmp_path, out, *args: str) -> tuple[int, subprocess.CompletedProcess[str]]:
    """How many times `orbitrig sweep ARGS` opens DIR/run.json (every process it starts included)."""
    trace = tmp_path / "opens.txt"
    cmd = ["strace", "-f", "-qq", "-e", "trace=openat", "-o", str(trace), *orbitrig_cmd("sweep", *args)]
    p = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=180)
    return sum(f'"{out / "run.json"}"' in line for line in trace.read_text().splitlines()), p


def test_a_resume_reads_the_run_header_once(tmp_path):
    matrix, out = tmp_path / "two.toml", tmp_path / "run"
    matrix.write_text(small_matrix("two", 8))
    args = ("sweep", "--sim", "--matrix", str(matrix), "--out", str(out), "--speedup", "50", "--no-draw-figures")
    first = orbitrig(*args, timeout=180, columns=None)
    assert first.returncode == 0, first.stderr
    opens, dry = _opens_of_header(tmp_path, out, "--sim", "--dry-run", "--resume", str(out))
    assert dry.returncode == 0 and "resume: 2 of 2 points complete (0000, 0001)" in dry.stdout, dry.stderr
    assert opens == 1
    opens, nothing = _opens_of_header(tmp_path, out, "--sim", "--resume", str(out))
    assert nothing.returncode == 0 and "nothing left to do" in nothing.stdout, nothing.stderr
    assert opens == 1
