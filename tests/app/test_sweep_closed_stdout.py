"""A sweep whose standard output's reader is gone (`orbitrig sweep --sim ... | head -1`): the run
completes and its exit status says so; the closing table, which cannot be printed, changes
nothing (no run-directory error, no failure)."""

from __future__ import annotations


import h5py
import pytest

from support.store_checks import small_matrix
from support.cli_helpers import closed_pipe, orbitrig_into

pytestmark = pytest.mark.timeout(180)


def test_a_completed_sweep_into_a_closed_pipe_exits_0(tmp_path):
    (tmp_path / "m.toml").write_text(small_matrix("head", 10, spin_rpm=(1000.0,)))
    out = tmp_path / "run"
    with closed_pipe() as w:  # the reader (`head -1`) gone before the table
        proc = orbitrig_into(w, "sweep", "--sim", "--matrix", str(tmp_path / "m.toml"), "--out", str(out), timeout=150)
    with h5py.File(out / "run.h5", "r") as f:
        assert str(f.attrs["status"]) == "completed"
    assert proc.returncode == 0, proc.stderr
    assert "run completed" in proc.stderr and "error:" not in proc.stderr and "Traceback" not in proc.stderr
