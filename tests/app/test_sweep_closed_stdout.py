"""A sweep whose standard output's reader is gone (`orbitrig sweep --sim ... | head -1`): the run
completes and its exit status says so; the closing table, which cannot be printed, changes
nothing (no run-directory error, no failure)."""

from __future__ import annotations

import os
import subprocess

import h5py
import pytest

from support.paths import ROOT
from support.store_checks import small_matrix
from support.cli_helpers import orbitrig_cmd

pytestmark = pytest.mark.timeout(180)


def test_a_completed_sweep_into_a_closed_pipe_exits_0(tmp_path):
    (tmp_path / "m.toml").write_text(small_matrix("head", 10, spin_rpm=(1000.0,)))
    out = tmp_path / "run"
    r, w = os.pipe()
    os.close(r)  # the reader (`head -1`) gone before the table
    try:
        proc = subprocess.run(
            orbitrig_cmd("sweep", "--sim", "--matrix", str(tmp_path / "m.toml"), "--out", str(out)),
            cwd=ROOT,
            stdin=subprocess.DEVNULL,
            stdout=w,
            stderr=subprocess.PIPE,
            text=True,
            timeout=150,
        )
    finally:
        os.close(w)
    with h5py.File(out / "run.h5", "r") as f:
        assert str(f.attrs["status"]) == "completed"
    assert proc.returncode == 0, proc.stderr
    assert "run completed" in proc.stderr and "error:" not in proc.stderr and "Traceback" not in proc.stderr
