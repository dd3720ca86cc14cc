"""Activating a calibration record replaces rig.toml as one durable step (orbitrig.config.activate):
a file that cannot be written (read-only, immutable, too little room) is left exactly as it was,
the failure a ConfigError naming rig.toml, and `orbitrig calibrate` says the record was written
but not activated (exit 2, no traceback). A file size limit (RLIMIT_FSIZE below rig.toml's size)
stands in for a disk that fills while rig.toml is written: the same EFBIG/ENOSPC path of write(2)."""

from __future__ import annotations

import resource
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from orbitrig.config import activate, load_rig
from orbitrig.errors import ConfigError

from support.paths import ROOT
from support.rig_configs import lab_record_config
from support.cli_helpers import orbitrig

NAME = "2026-12-01T083000Z-loads"
LIMIT = 4096  # bytes, below rig.toml's size (about 6 kB)


def _rig(tmp: Path) -> Path:
    shutil.copy(ROOT / "config/rig.toml", tmp / "rig.toml")
    return tmp / "rig.toml"


def _limited() -> None:
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT, LIMIT))


def test_a_read_only_rig_toml_is_refused_and_left_unchanged(tmp_path):
    rig = _rig(tmp_path)
    before = rig.read_bytes()
    rig.chmod(0o444)
    with pytest.raises(ConfigError, match=r"rig\.toml: cannot write it: it is read-only \(mode 444\); left unchanged"):
        activate(rig, NAME)
    assert rig.read_bytes() == before and oct(rig.stat().st_mode & 0o777) == "0o444"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rig.toml"]


def test_an_immutable_rig_toml_is_refused_and_left_unchanged(tmp_path):
    rig = _rig(tmp_path)
    before = rig.read_bytes()
    if shutil.which("chattr") is None or subprocess.run(["chattr", "+i", str(rig)], capture_output=True).returncode:
        pytest.skip("chattr +i not available here (needs root on a file system with the immutable flag)")
    try:
        with pytest.raises(ConfigError, match=r"rig\.toml: cannot write it: write access refused"):
            activate(rig, NAME)
    finally:
        subprocess.run(["chattr", "-i", str(rig)], check=True)
    assert rig.read_bytes() == before


def test_a_write_that_runs_out_of_room_leaves_rig_toml_whole(tmp_path):
    rig = _rig(tmp_path)
    before = rig.read_bytes()
    assert len(before) > LIMIT
    code = f"from orbitrig.config import activate\nactivate({str(rig)!r}, {NAME!r})"
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, preexec_fn=_limited, capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 1
    assert f"ConfigError: {rig}: cannot write: OSError: File too large; left unchanged" in proc.stderr, proc.stderr
    assert rig.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rig.toml"]  # no temporary file left


def test_activation_keeps_the_mode_and_writes_through_a_symbolic_link(tmp_path):
    real = _rig(tmp_path)
    real.chmod(0o640)
    link = tmp_path / "link.toml"
    link.symlink_to(real)
    activate(link, NAME)
    assert link.is_symlink() and oct(real.stat().st_mode & 0o777) == "0o640"
    assert f'calibration_record = "{NAME}"' in real.read_text()


@pytest.mark.timeout(120)
def test_calibrate_says_the_record_was_written_but_not_activated(tmp_path):
    rig = lab_record_config(tmp_path)
    before = rig.read_bytes()
    records = sorted(p.name for p in (tmp_path / "calibration").iterdir())
    args = ("calibrate", "runout", "--sim", "--config", str(rig), "--operator", "t", "--revolutions", "5")
    proc = orbitrig(*args, timeout=110, preexec_fn=_limited)
    (new,) = sorted(set(p.name for p in (tmp_path / "calibration").iterdir()) - set(records))
    name = new.removesuffix(".toml")
    assert proc.returncode == 2, proc.stderr
    assert f"error: {rig}: cannot write: OSError: File too large; left unchanged" in proc.stderr, proc.stderr
    assert f"{rig}: record {name} written, not activated" in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr
    assert rig.read_bytes() == before and load_rig(rig).calibration_record != name
