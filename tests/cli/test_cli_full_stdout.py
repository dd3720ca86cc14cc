"""Standard output on a full disk (`orbitrig calibrate show > file`, the file system full:
/dev/full gives ENOSPC on every write): the command fails (non-zero exit) and says why on
standard error, without a traceback; a reader gone away (`| head`) stays no failure
(tests/cli/test_cli_basics.py, tests/app/test_sweep_closed_stdout.py)."""

from __future__ import annotations

import os
import subprocess

import pytest

from support.cli_helpers import orbitrig_cmd
from support.paths import ROOT

FULL = "cannot write standard output: No space left on device"


def _into_full_disk(*args: str) -> subprocess.CompletedProcess:
    with open("/dev/full", "w") as full:
        return subprocess.run(
            orbitrig_cmd(*args),
            cwd=ROOT,
            env={**os.environ, "NO_COLOR": "1"},
            stdin=subprocess.DEVNULL,
            stdout=full,
            stderr=subprocess.PIPE,
            text=True,
            timeout=120,
        )


@pytest.mark.parametrize("command", [("calibrate", "show"), ("calibrate", "list")])
def test_a_calibration_record_printed_onto_a_full_disk_fails_saying_so(command):
    p = _into_full_disk(*command)
    assert p.returncode == 1, p.stderr
    assert p.stderr == f"error: {FULL}\n"


def test_a_dry_run_printed_onto_a_full_disk_fails_naming_standard_output():
    p = _into_full_disk("sweep", "--sim", "--dry-run")
    assert p.returncode == 1, p.stderr
    assert p.stderr == "error: standard output: No space left on device\n"
