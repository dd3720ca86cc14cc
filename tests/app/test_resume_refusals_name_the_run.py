"""A resume refused before anything starts names what exists of a killed run (its directory,
its run.json), never the run.h5 such a run does not have yet."""

from __future__ import annotations

import subprocess

import pytest

from orbitrig import config as cfg
from orbitrig.store.writer import RunStore

from support.cli_helpers import orbitrig
from support.store_checks import small_matrix

pytestmark = pytest.mark.timeout(120)


def _sweep(*args: str) -> subprocess.CompletedProcess[str]:
    return orbitrig("sweep", *args, timeout=60, columns=None)


def test_resume_refusals_of_a_killed_run_name_its_directory(tmp_path):
    rig = cfg.load_rig()
    mat = cfg.matrix_from_text(small_matrix("killed", 8), "killed.toml")
    out = tmp_path / "run"
    RunStore.create(out, rig_text=rig.text, matrix_text=mat.run_text, matrix_name=mat.name, sim=True)
    assert not (out / "run.h5").exists()  # as a killed run leaves it
    p = _sweep("--resume", "--out", str(out))  # made on the simulator, resumed without --sim
    assert p.returncode == 2, p.stdout + p.stderr
    text = " ".join(p.stderr.split())
    assert f"{out}/run.json: this run was made on the simulator: resume it with --sim" in text, text
    other = tmp_path / "other.toml"
    other.write_text(small_matrix("other", 9))
    p = _sweep("--sim", "--resume", "--out", str(out), "--matrix", str(other))
    assert p.returncode == 2, p.stdout + p.stderr
    text = " ".join(p.stderr.split())
    assert f"differs from the matrix of the run being resumed in {out} in name, revolutions; resume without" in text
    assert "run.h5" not in text
    # the key that differs is named as the rig configuration's are ([section] key)
    other.write_text(small_matrix("killed", 8, spin_rpm=(1000.0, 2500.0)))
    p = _sweep("--sim", "--resume", "--out", str(out), "--matrix", str(other))
    assert p.returncode == 2, p.stdout + p.stderr
    text = " ".join(p.stderr.split())
    assert f"resumed in {out} in [operating] spin_rpm; resume without --matrix (the stored one is used)" in text, text
    other.write_text("# a comment\n" + small_matrix("killed", 8))
    p = _sweep("--sim", "--resume", "--out", str(out), "--matrix", str(other))
    assert p.returncode == 2 and f"resumed in {out} in its text (comments or layout); " in p.stderr, p.stderr
