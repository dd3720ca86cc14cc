"""The command line's one boundary for standard output (orbitrig.cli.boundary, run by
orbitrig.cli.main): every command, `--help` and `--version` among them, into a reader gone
before it prints exits 0 saying nothing, and onto a full disk (/dev/full) fails with the one error
line naming standard output, exit 1. Before, click's own handling ended the first with exit 1 and
the second with a traceback. An error of neither stream (a file, a socket) is not taken for one."""

from __future__ import annotations

import errno
import os
import shlex
import subprocess
import sys

import pytest

from orbitrig.cli.boundary import STDOUT, failed_stream
from orbitrig.cli.terminal import OutputError
from support.cli_helpers import child_env, closed_pipe, orbitrig_cmd, orbitrig_into
from support.paths import ROOT
from support.report_synthetic import write_synthetic_run

FULL = "error: standard output: No space left on device"
UNBUFFERED = {"PYTHONUNBUFFERED": "1"}
BUFFERED = {"PYTHONUNBUFFERED": None}  # standard output block-buffered: the failure at a flush
SAMPLE = [
    ("--help",),
    ("--version",),
    ("version",),
    ("drives", "--help"),
    ("drives", "run", "--help"),
    ("sweep", "--help"),
    ("catalog", "list", "--help"),
]


def _into_closed_pipe(*args: str, env: dict[str, str | None] = UNBUFFERED) -> subprocess.CompletedProcess:
    """`orbitrig ARGS` writing into a pipe whose reader closed before it started: every write fails
    (EPIPE), at once and every time."""
    with closed_pipe() as write_end:
        return orbitrig_into(write_end, *args, env=env)


def _onto_full_disk(*args: str, env: dict[str, str | None] = UNBUFFERED) -> subprocess.CompletedProcess:
    with open("/dev/full", "w") as full:
        return orbitrig_into(full, *args, env=env)


def _command(args: tuple[str, ...]) -> str:
    """The command the error line names: the sub-commands resolved before --help ('orbitrig' alone)."""
    words = [a for a in args if not a.startswith("-")]
    return " ".join(["orbitrig", *words])


@pytest.mark.parametrize("env", [UNBUFFERED, BUFFERED], ids=["unbuffered", "buffered"])
@pytest.mark.parametrize("args", SAMPLE, ids=" ".join)
def test_help_and_version_into_a_gone_reader_exit_0_saying_nothing(args, env):
    p = _into_closed_pipe(*args, env=env)
    assert (p.returncode, p.stderr) == (0, "")


@pytest.mark.parametrize("env", [UNBUFFERED, BUFFERED], ids=["unbuffered", "buffered"])
@pytest.mark.parametrize("args", SAMPLE, ids=" ".join)
def test_help_and_version_onto_a_full_disk_fail_naming_standard_output(args, env):
    p = _onto_full_disk(*args, env=env)
    assert (p.returncode, p.stderr) == (1, f"{_command(args)}: {FULL}\n")


@pytest.mark.parametrize("args", [("--help",), ("--version",), ("sweep", "--help")], ids=" ".join)
def test_a_reader_that_stops_after_one_byte_ends_the_printing_only(args):
    """`orbitrig ... | head -c1` under pipefail: whether the write met the closed pipe or not, exit 0 and
    nothing on standard error."""
    cmd = f"{shlex.join(orbitrig_cmd(*args))} | head -c1"
    p = subprocess.run(
        ["bash", "-o", "pipefail", "-c", cmd], cwd=ROOT, env=child_env(), capture_output=True, text=True, timeout=120
    )
    assert (p.returncode, len(p.stdout), p.stderr) == (0, 1, "")


@pytest.mark.parametrize("output", [(), ("--json",)], ids=["text", "json"])
def test_design_prints_through_the_boundary(output):
    """`design` prints its proposal last, with no handling of its own: into a gone reader exit 0,
    onto a full disk the error line, exit 1."""
    args = ("design", "--model", "kc8", "--spin", "1000", "--matrix", "demo", *output)
    p = _into_closed_pipe(*args)
    assert (p.returncode, p.stderr) == (0, "")
    p = _onto_full_disk(*args)
    assert (p.returncode, p.stderr) == (1, f"orbitrig design: {FULL}\n")


def test_the_catalogs_csv_on_standard_output_prints_through_the_boundary(tmp_path):
    pytest.importorskip("sqlalchemy")
    runs = tmp_path / "runs"
    write_synthetic_run(runs / "run1", n_points=1, incomplete=0)
    add = subprocess.run(orbitrig_cmd("catalog", "add", str(runs / "run1")), cwd=ROOT, env=child_env(), timeout=120)
    assert add.returncode == 0
    args = ("catalog", "export", "--format", "csv", "--runs", str(runs))
    p = _into_closed_pipe(*args)
    assert (p.returncode, p.stderr) == (0, "")
    p = _onto_full_disk(*args)
    assert (p.returncode, p.stderr) == (1, f"orbitrig catalog export: {FULL}\n")


def test_a_full_disk_or_a_broken_pipe_elsewhere_is_not_standard_outputs(monkeypatch):
    """Standard output a pipe with its reader there: an ENOSPC (a file of the command) or an EPIPE
    (a socket of the command) is no failure of standard output, nor is the ENOSPC with /dev/full
    there (only its own write says so: an OutputError); a pipe whose reader is gone, the EPIPE is."""
    enospc = OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    epipe = BrokenPipeError(errno.EPIPE, os.strerror(errno.EPIPE))
    read_end, write_end = os.pipe()
    try:
        with os.fdopen(os.dup(write_end), "w") as pipe, open("/dev/full", "w") as full:
            monkeypatch.setattr(sys, "stdout", pipe)
            monkeypatch.setattr(sys, "stderr", pipe)
            assert (failed_stream(enospc), failed_stream(epipe)) == (None, None)
            monkeypatch.setattr(sys, "stdout", full)
            assert failed_stream(enospc) is None
            assert failed_stream(OutputError(errno.ENOSPC, os.strerror(errno.ENOSPC), STDOUT)) == STDOUT
            monkeypatch.setattr(sys, "stdout", pipe)
            os.close(read_end)
            read_end = -1
            assert failed_stream(epipe) == STDOUT
    finally:
        os.close(write_end)
        if read_end >= 0:
            os.close(read_end)


def _errors_into(stderr: int | object, *args: str) -> int:
    """The exit status of `orbitrig ARGS` with its standard error onto `stderr`, its output piped."""
    return subprocess.run(
        orbitrig_cmd(*args),
        cwd=ROOT,
        env=child_env(),
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=stderr,  # type: ignore[arg-type]
        timeout=120,
    ).returncode


@pytest.mark.parametrize(
    ("args", "code"),
    [
        (("sweep", "--no-such-option"), 2),  # click's usage error
        (("export", "/nonexistent/run"), 2),  # the command's own (failure.fail)
    ],
    ids=["click", "fail"],
)
def test_an_error_standard_error_cannot_take_keeps_its_exit_status(args, code):
    """A usage error said onto a closed pipe or a full disk still exits 2 (before: 1, the failed
    write taken for the outcome)."""
    with closed_pipe() as write_end:
        assert _errors_into(write_end, *args) == code
    with open("/dev/full", "w") as full:
        assert _errors_into(full, *args) == code


def test_a_quota_or_size_error_of_another_file_is_not_a_regular_files_standard_outputs(tmp_path, monkeypatch):
    """Standard output `> file` with room to spare: an EDQUOT or EFBIG the command met writing
    another file is no failure of standard output (before: any such error was blamed on it)."""
    with open(tmp_path / "out.txt", "w") as out:
        monkeypatch.setattr(sys, "stdout", out)
        out.write("a table\n")  # pending, and writable
        for code in (errno.EDQUOT, errno.EFBIG):
            assert failed_stream(OSError(code, os.strerror(code))) is None
