"""`orbitrig sweep`'s exit status when the run directory fails at the start (README's table:
1 failed, 2 bad configuration or usage): a disk that is full when the run is created fails
the command (1), as any storage failure does; a directory that holds no run to resume, or
whose header is not a run's, is the caller's mistake (2). On a real tmpfs, filled up."""

import subprocess

import pytest

from support.cli_helpers import orbitrig

pytestmark = pytest.mark.timeout(120)


def _sweep(*args: str) -> subprocess.CompletedProcess:
    return orbitrig("sweep", "--sim", *args, timeout=90, columns=None)


@pytest.fixture
def full_disk(tmp_path):
    """A 1 MB tmpfs with no byte left; unmounted afterwards."""
    mnt = tmp_path / "disk"
    mnt.mkdir()
    subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(mnt)], check=True)
    try:
        subprocess.run(["dd", "if=/dev/zero", f"of={mnt / 'fill'}", "bs=4k"], capture_output=True, check=False)
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], check=False)


def test_a_disk_full_when_the_run_is_created_fails_the_sweep_with_exit_1(full_disk):
    out = full_disk / "run"
    p = _sweep("--out", str(out))
    assert p.returncode == 1, p.stderr
    assert "Traceback" not in p.stderr
    assert f"error: {out / 'run.json'}: cannot write: No space left on device" in p.stderr
    assert "resume" not in p.stderr  # no run was made: there is nothing to resume
    assert "start the run again" in p.stderr
    assert not (out / "run.json").exists()


@pytest.mark.parametrize("header", [None, "not json"])
def test_a_resume_of_a_directory_without_a_run_is_a_usage_error_exit_2(tmp_path, header):
    out = tmp_path / "run"
    (out / "points").mkdir(parents=True)
    if header is not None:
        (out / "run.json").write_text(header)
    p = _sweep("--resume", str(out))
    assert p.returncode == 2, p.stderr
    assert "Traceback" not in p.stderr
    expect = "nothing to resume" if header is None else "not a readable run header"
    assert expect in p.stderr, p.stderr
