"""`sweep --resume` of a run that has nothing left (every point complete, run.h5 written) says so
and exits 0 without starting anything: no simulator, no drives, the run directory as it was (it
started the simulator and "resumed", writing a new session into the journal and run.log).

Real parts: the `orbitrig` command line (subprocesses) on the simulator."""

from __future__ import annotations

import subprocess

import pytest

from support.cli_helpers import orbitrig
from support.store_checks import small_matrix

pytestmark = pytest.mark.timeout(240)


def _sweep(*args: str) -> subprocess.CompletedProcess[str]:
    return orbitrig("sweep", *args, timeout=180, columns=None)


def _files(out):
    return {p.relative_to(out): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}


@pytest.mark.parametrize(
    "spins, points",
    [((1000.0, 2000.0), "all 2 points of the run in {} are"), ((1000.0,), "the one point of the run in {} is")],
)
def test_a_resume_of_a_complete_run_has_nothing_left_to_do(tmp_path, spins, points):
    matrix, out = tmp_path / "two.toml", tmp_path / "run"
    matrix.write_text(small_matrix("two", 8, spins))
    first = _sweep("--sim", "--matrix", str(matrix), "--out", str(out), "--speedup", "50", "--no-draw-figures")
    assert first.returncode == 0 and (out / "run.h5").is_file(), first.stderr
    before = _files(out)
    again = _sweep("--sim", "--resume", str(out))
    assert again.returncode == 0, again.stderr
    said = f"resume: {points.format(out)} complete and its run.h5 is written: nothing left to do"
    assert said in again.stdout + again.stderr, again.stdout + again.stderr
    assert "simulator scenario of the run" not in again.stderr  # the simulator was not started
    assert _files(out) == before  # no session, no aside, nothing rewritten
