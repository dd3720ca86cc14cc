"""`orbitrig export` onto a full disk (a small tmpfs, filled): the message names the file being
written and says "write" (not "read" of the run's piece it was copying), advises to export
again (not to resume a run), and leaves no temporary file."""

from __future__ import annotations

import os
import subprocess

import pytest
from typer.testing import CliRunner

from orbitrig.cli import app

from support.store_checks import fill

pytestmark = pytest.mark.timeout(120)

#: room left on the filled disk: enough to start each file, not to finish it (bytes)
ROOM = 96 * 1024


@pytest.mark.parametrize("fmt", ["h5", "tdms"])
def test_export_onto_a_full_disk_names_the_file_it_writes(synthetic, tiny_disk, fmt):
    filler = fill(tiny_disk)
    os.truncate(filler, filler.stat().st_size - ROOM)
    out = tiny_disk / "export"
    res = CliRunner().invoke(app, ["export", str(synthetic), "--format", fmt, "--out", str(out)])
    assert res.exit_code == 1, res.output
    message = res.stderr.strip()
    name = "run.h5" if fmt == "h5" else "run.tdms"
    assert message.startswith(f"orbitrig export: error: {out / name}: cannot write: No space left on device"), message
    assert "free space, then export again" in message and "resume" not in message, message
    assert "read" not in message and str(synthetic) not in message, message
    assert not list(out.glob("*.tmp"))


def test_export_onto_a_disk_too_full_for_its_directory_advises_to_export_again(synthetic, tiny_disk):
    """The export directory cannot be made (the disk full, blocks and inodes): the error names
    it and, as every full disk of an export, advises to export again."""
    fill(tiny_disk)
    st = os.statvfs(tiny_disk)
    subprocess.run(["mount", "-o", f"remount,nr_inodes={st.f_files - st.f_ffree}", str(tiny_disk)], check=True)
    out = tiny_disk / "export"
    res = CliRunner().invoke(app, ["export", str(synthetic), "--format", "csv", "--out", str(out)])
    assert res.exit_code == 1, res.output
    message = res.stderr.strip()
    assert message.startswith(
        f"orbitrig export: error: {out}: cannot create the export directory: No space left on device"
    ), message
    assert "free space, then export again" in message and "resume" not in message, message
    assert not out.exists()
