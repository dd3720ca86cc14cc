"""Standard output on a full disk (`orbitrig calibrate show > file`, the file system full:
/dev/full gives ENOSPC on every write): the command fails (non-zero exit) and says why on
standard error, without a traceback; a reader gone away (`| head`) stays no failure
(tests/cli/test_cli_basics.py, tests/app/test_sweep_closed_stdout.py). A run's console on
standard error is the exception: a full disk there makes it quiet, the run's exit status stays."""

from __future__ import annotations

import contextlib
import fcntl
import os
import shutil
import subprocess
import sys
import termios
import time

import h5py
import pytest

from orbitrig.cli.terminal import TerminalConsole, off_the_loop
from support.cli_helpers import orbitrig_cmd
from support.paths import ROOT
from support.rig_configs import patient_rig_config
from support.store_checks import small_matrix

FULL = "standard output: No space left on device"


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
    assert p.stderr == f"orbitrig {' '.join(command)}: error: {FULL}\n"


def test_a_dry_run_printed_onto_a_full_disk_fails_naming_standard_output():
    p = _into_full_disk("sweep", "--sim", "--dry-run")
    assert p.returncode == 1, p.stderr
    assert p.stderr == "orbitrig sweep: error: standard output: No space left on device\n"


def test_a_sweeps_closing_table_printed_onto_a_full_disk_fails_the_command_not_the_run(tmp_path):
    (tmp_path / "m.toml").write_text(small_matrix("full", 10, spin_rpm=(1000.0,)))
    out = tmp_path / "run"
    p = _into_full_disk("sweep", "--sim", "--matrix", str(tmp_path / "m.toml"), "--out", str(out))
    assert p.returncode == 1, p.stderr
    assert "run completed: all points completed" in p.stderr and "Traceback" not in p.stderr
    assert p.stderr.endswith("error: standard output: No space left on device\n"), p.stderr[-500:]
    with h5py.File(out / "run.h5", "r") as f:
        assert str(f.attrs["status"]) == "completed"


def test_a_calibration_steps_numbers_printed_onto_a_full_disk_still_write_its_record(tmp_path):
    """The runout step measured (the drives turned, both stopped), its numbers meet a full disk on
    standard output: the step fails saying so, and the record it measured is written and active
    all the same, the error naming it. It was lost: the numbers were printed before the record
    was written, and the output's failure ended the step there."""
    rig = patient_rig_config(tmp_path)
    shutil.copytree(ROOT / "config" / "calibration", tmp_path / "calibration")
    before = {p.name for p in (tmp_path / "calibration").iterdir()}
    p = _into_full_disk("calibrate", "runout", "--sim", "--config", str(rig), "--revolutions", "10", "--speedup", "20")
    assert p.returncode == 1, p.stderr
    (new,) = {p.name for p in (tmp_path / "calibration").iterdir()} - before
    name = new.removesuffix(".toml")
    assert name.endswith("-runout"), new
    assert f'calibration_record = "{name}"' in rig.read_text()
    assert p.stderr.index("both drives stopped") < p.stderr.index(FULL), p.stderr
    assert p.stderr.endswith(
        f"error: {FULL} (record {name} written to {tmp_path / 'calibration'} and made active; "
        f"its numbers: orbitrig calibrate show {name})\n"
    ), p.stderr
    assert "Traceback" not in p.stderr


F_GETPIPE_SZ = 1032  # fcntl: a pipe's capacity, bytes


def test_a_disk_full_after_the_consoles_last_line_leaves_the_command_its_exit(monkeypatch):
    """Standard error fills up while the console's closing line waits for its thread (the line
    before still held by a reader that does not read): the console goes quiet; the streams are
    given back (off_the_loop) without an OutputError, so a completed sweep still exits 0."""
    read_end, write_end = os.pipe()
    held = 4 * fcntl.fcntl(write_end, F_GETPIPE_SZ)  # more than the pipe holds: the write waits for its reader
    stream = os.fdopen(write_end, "w")
    monkeypatch.setattr(sys, "stderr", stream)
    try:
        with off_the_loop():
            console = TerminalConsole(file=sys.stderr)
            console.print("x" * held, markup=False, highlight=False, soft_wrap=True)
            _until_in_pipe(read_end)  # the stream's thread is in that write
            console.print("run completed", markup=False)  # waits behind it, after the console's last flush
            full = os.open("/dev/full", os.O_WRONLY)
            os.dup2(full, write_end)  # the disk is full from here on
            os.close(full)
            got = 0
            while got < held:  # the reader reads: the first write ends, the closing line meets ENOSPC
                got += len(os.read(read_end, 1 << 16))
            console.written(10)
        assert console.quiet
    finally:
        os.close(read_end)
        with contextlib.suppress(OSError):
            stream.close()


def _until_in_pipe(read_end: int, timeout: float = 10) -> None:
    """Wait until something was written into the pipe of ``read_end``."""
    deadline = time.monotonic() + timeout
    while not int.from_bytes(fcntl.ioctl(read_end, termios.FIONREAD, b"\0\0\0\0"), sys.byteorder):
        assert time.monotonic() < deadline, "nothing written into the pipe"
        time.sleep(0.01)
