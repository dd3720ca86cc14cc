"""Standard output `> file` that cannot take what a command prints, unbuffered (``python -u``,
PYTHONUNBUFFERED=1) as buffered: a quota that refuses the file (EDQUOT) and the file size limit
(``ulimit -f``: a short write, then EFBIG) end in the one error line naming standard output and
exit 1. Before, unbuffered, the first ended in a traceback and the second exited 0, the file cut
short. A file of the command's own failing on the disk that holds standard output too is that
file's failure, not standard output's (before: blamed on standard output, which had all it was
given)."""

from __future__ import annotations

import errno
import itertools
import resource
import subprocess
import sys

import pytest

from support.cli_helpers import child_env
from support.paths import ROOT
from support.refused_writes import writes_refused
from support.small_disk import mounted_tmpfs
from support.store_checks import fill

UNBUFFERED = {"PYTHONUNBUFFERED": "1"}
BUFFERED = {"PYTHONUNBUFFERED": None}
#: bytes standard output's file may hold under the file size limit: less than any output below
LIMIT = 10
SHORT = [
    ("--help",),
    ("--version",),
    ("version",),
    ("drives", "--help"),
    ("calibrate", "list"),
    ("design", "--model", "kc8", "--spin", "1000", "--matrix", "demo"),
]


def _command(args: tuple[str, ...]) -> str:
    """The command the error line names: the words before the first option ('orbitrig' alone)."""
    return " ".join(["orbitrig", *itertools.takewhile(lambda a: not a.startswith("-"), args)])


def _size_limited() -> None:
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT, hard))


def _into_file(path, *args: str, env, preexec) -> subprocess.CompletedProcess:
    with open(path, "w") as out:
        return subprocess.run(
            [sys.executable, "-m", "orbitrig", *args],
            cwd=ROOT,
            env=child_env({"NO_COLOR": "1", **env}),
            stdin=subprocess.DEVNULL,
            stdout=out,
            stderr=subprocess.PIPE,
            text=True,
            timeout=120,
            preexec_fn=preexec,
        )


@pytest.mark.parametrize(
    ("args", "env"),
    [(a, UNBUFFERED) for a in SHORT] + [(("--help",), BUFFERED), (("--version",), BUFFERED)],
    ids=[f"{' '.join(a)}-unbuffered" for a in SHORT] + ["--help-buffered", "--version-buffered"],
)
def test_output_beyond_the_file_size_limit_fails_naming_standard_output(tmp_path, args, env):
    out = tmp_path / "out.txt"
    p = _into_file(out, *args, env=env, preexec=_size_limited)
    assert (p.returncode, p.stderr) == (1, f"{_command(args)}: error: standard output: File too large\n")
    assert out.stat().st_size == LIMIT


@pytest.mark.parametrize("env", [UNBUFFERED, BUFFERED], ids=["unbuffered", "buffered"])
@pytest.mark.parametrize("args", [("--help",), ("--version",), SHORT[-1]], ids=["--help", "--version", "design"])
def test_a_quota_that_refuses_standard_output_fails_naming_it(tmp_path, args, env):
    p = _into_file(tmp_path / "out.txt", *args, env=env, preexec=writes_refused(1, errno.EDQUOT))
    assert (p.returncode, p.stderr) == (1, f"{_command(args)}: error: standard output: Disk quota exceeded\n")


#: a command that prints a line, then fills the disk writing its data (a file of its own, bare
#: OSError of a file object: no file name), through the command line's boundary
DATA_FILLS_THE_DISK = """
import sys, click
from orbitrig.cli.boundary import run

@click.command()
def command():
    click.echo("point 0000 complete")
    sys.stdout.flush()
    with open(sys.argv[1], "wb") as data:
        for _ in range(4096):  # 4 MB at most: more than the disk holds
            data.write(b"\\0" * 1024)
            data.flush()

run(lambda: command.main(args=[]))
"""


def test_a_data_file_filling_the_disk_of_standard_output_is_not_standard_outputs(tmp_path):
    with mounted_tmpfs(tmp_path / "disk", "1m") as disk:
        out = disk / "out.txt"
        with open(out, "w") as stdout:
            p = subprocess.run(
                [sys.executable, "-c", DATA_FILLS_THE_DISK, str(disk / "run.dat")],
                cwd=ROOT,
                env=child_env(UNBUFFERED),
                stdin=subprocess.DEVNULL,
                stdout=stdout,
                stderr=subprocess.PIPE,
                text=True,
                timeout=60,
            )
        assert out.read_text() == "point 0000 complete\n"
    assert "standard output" not in p.stderr, p.stderr
    assert p.returncode == 1
    assert p.stderr.endswith("OSError: [Errno 28] No space left on device\n"), p.stderr[-500:]


def test_a_file_of_the_command_on_the_full_disk_of_standard_output_is_not_its(tmp_path, monkeypatch):
    """In the process: standard output a file on a full tmpfs; the ENOSPC of another file there is
    not standard output's; one its own write raised (StandardFile) is."""
    import io

    from orbitrig.cli.boundary import STDOUT, StandardFile, failed_stream

    with mounted_tmpfs(tmp_path / "disk", "1m") as disk:
        with open(disk / "out.txt", "w") as plain:
            monkeypatch.setattr(sys, "stdout", plain)
            fill(disk)
            with pytest.raises(OSError) as data:
                (disk / "run.dat").write_bytes(b"\0" * 8192)
            assert data.value.errno == errno.ENOSPC
            assert failed_stream(data.value) is None
            with io.TextIOWrapper(io.BufferedWriter(StandardFile(plain.fileno(), STDOUT))) as tagged:
                monkeypatch.setattr(sys, "stdout", tagged)
                tagged.write("x" * 8192)
                with pytest.raises(OSError) as own:
                    tagged.flush()
                assert (failed_stream(own.value), own.value.errno) == (STDOUT, errno.ENOSPC)
