"""Running the `orbitrig` command of this source tree as a user does: a subprocess, or in this process for a command that starts no process."""

from __future__ import annotations

import asyncio
import contextlib
import os
import signal
import subprocess
import sys
import warnings
from collections.abc import AsyncIterator, Iterator
from pathlib import Path
from typing import IO

from .paths import ROOT


def orbitrig_cmd(*args: str) -> list[str]:
    """The command line of `orbitrig ARGS...` of this source tree (`python -m orbitrig`)."""
    return [sys.executable, "-m", "orbitrig", *args]


def orbitrig(
    *args: str,
    timeout: float | None = 120,
    cwd: Path = ROOT,
    columns: int | None = 200,
    env: dict[str, str | None] | None = None,
    **kw,
) -> subprocess.CompletedProcess:
    """`orbitrig ARGS...` (as `python -m orbitrig`) run to its end: output captured as text,
    ``columns`` wide (None: COLUMNS unset, 80 as a pipe is), no colour, standard input closed, from
    ``cwd``, ``env`` added to the environment (as `child_env`)."""
    wide = None if columns is None else str(columns)
    return subprocess.run(
        orbitrig_cmd(*args),
        cwd=cwd,
        env=child_env({"COLUMNS": wide, "NO_COLOR": "1", **(env or {})}),
        capture_output=True,
        text=True,
        timeout=timeout,
        stdin=subprocess.DEVNULL,
        **kw,
    )


def child_env(env: dict[str, str | None] | None = None) -> dict[str, str]:
    """This process's environment with this source tree first on PYTHONPATH, and ``env`` added
    (a variable None there: unset)."""
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p)
    full = {**os.environ, "PYTHONPATH": path, **(env or {})}
    return {k: v for k, v in full.items() if v is not None}


def orbitrig_into(
    stdout: int | IO, *args: str, env: dict[str, str | None] | None = None, timeout: float = 120
) -> subprocess.CompletedProcess:
    """`orbitrig ARGS` with standard output onto `stdout` (a descriptor or file: a pipe whose reader
    closed, /dev/full), standard error captured as text, standard input empty."""
    return subprocess.run(
        orbitrig_cmd(*args),
        cwd=ROOT,
        env=child_env(env),
        stdin=subprocess.DEVNULL,
        stdout=stdout,
        stderr=subprocess.PIPE,
        text=True,
        timeout=timeout,
    )


@contextlib.contextmanager
def closed_pipe() -> Iterator[int]:
    """The write end of a pipe whose reader has closed (``| head`` gone): every write fails, EPIPE."""
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        yield write_end
    finally:
        os.close(write_end)


def started(
    cmd: list[str],
    *,
    cwd: Path = ROOT,
    env: dict[str, str | None] | None = None,
    stdin: int | IO | None = subprocess.DEVNULL,
    stdout: int | IO | None = subprocess.PIPE,
    stderr: int | IO | None = subprocess.PIPE,
    text: bool = True,
    **popen,
) -> subprocess.Popen:
    """``cmd`` started for a test to signal, read or kill: from ``cwd``, this source tree first on its
    PYTHONPATH and ``env`` added to this process's environment, its standard input closed and its
    output on text pipes unless said otherwise; ``popen``: further arguments of subprocess.Popen
    (``start_new_session``, ``preexec_fn``). End it with `reaped`."""
    return subprocess.Popen(
        cmd,
        cwd=cwd,
        env=child_env(env),
        stdin=stdin,
        stdout=stdout,
        stderr=stderr,
        text=text,
        **popen,
    )


def orbitrig_started(*args: str, **kw) -> subprocess.Popen:
    """`orbitrig ARGS...` started (as `python -m orbitrig`) as `started` starts a command."""
    return started(orbitrig_cmd(*args), **kw)


@contextlib.contextmanager
def reaped(proc: subprocess.Popen, stop: int = signal.SIGKILL, grace: float = 10.0) -> Iterator[subprocess.Popen]:
    """``proc`` for the block; after it, passed or failed, sent ``stop`` if it still runs (SIGKILL
    if it has not ended ``grace`` s later), waited for and its pipes closed. A failure in the block
    shows what the process had left on its standard error pipe (the test's captured stderr)."""
    try:
        yield proc
    except BaseException:
        ended(proc, stop, grace)
        sys.stderr.write(f"standard error of {proc.args}:\n{_left(proc)[-5000:]}\n")
        raise
    finally:
        ended(proc, stop, grace)
        for pipe in (proc.stdin, proc.stdout, proc.stderr):
            if pipe is not None:
                with contextlib.suppress(OSError):  # a pipe to a process gone: nothing to flush
                    pipe.close()


def ended(proc: subprocess.Popen, stop: int = signal.SIGKILL, grace: float = 10.0) -> int:
    """A process of the test's ended: sent ``stop`` if it still runs, SIGKILL if it has not ended
    ``grace`` s later; its exit status once reaped."""
    if proc.poll() is None:
        proc.send_signal(stop)
        try:
            proc.wait(grace)
        except subprocess.TimeoutExpired:
            proc.kill()
    return proc.wait()


def _left(proc: subprocess.Popen) -> str:
    """The rest of a process's standard error pipe: empty if it has none, a note if another process
    (a child of its own) still holds the pipe open after 5 s."""
    if proc.stderr is None or proc.stderr.closed:
        return ""
    try:
        err = proc.communicate(timeout=5)[1]
    except (subprocess.TimeoutExpired, ValueError, OSError):
        return "(not read: the pipe is still open)"
    return err.decode(errors="replace") if isinstance(err, bytes) else err or ""


#: warnings the interpreter does not show by default: a subprocess's standard error has none of them
UNSHOWN = (DeprecationWarning, PendingDeprecationWarning, ImportWarning, ResourceWarning)


def orbitrig_here(
    *args: str, cwd: Path = ROOT, columns: int = 200, env: dict[str, str | None] | None = None
) -> subprocess.CompletedProcess:
    """`orbitrig ARGS...` run in this process (no interpreter to start, the command line imported
    once) as `orbitrig()` runs it: from ``cwd``, output piped, ``columns`` wide (80: as a pipe is
    without COLUMNS), no colour, standard input empty, ``env`` set meanwhile (None: unset). The warnings a
    subprocess would print are added to its standard error; an exception escaping the command
    fails (a subprocess's traceback). For commands that start no process and move no drive:
    those run as a user runs them."""
    from typer.testing import CliRunner

    from orbitrig.cli import app

    def show(message, category, filename, lineno, file=None, line=None) -> None:
        sys.stderr.write(warnings.formatwarning(message, category, filename, lineno, line))  # the command's

    with contextlib.chdir(cwd), warnings.catch_warnings():
        warnings.simplefilter("default")  # each warning once per place, as a fresh interpreter shows it
        for category in UNSHOWN:
            warnings.simplefilter("ignore", category)
        warnings.showwarning = show  # where and when the interpreter writes it: standard error, at once
        r = CliRunner().invoke(app, list(args), env={"NO_COLOR": "1", "COLUMNS": str(columns), **(env or {})})
    assert r.exception is None or isinstance(r.exception, SystemExit), (args, r.exception, r.stderr)
    return subprocess.CompletedProcess(["orbitrig", *args], r.exit_code, r.stdout, r.stderr)


async def started_async(
    cmd: list[str],
    *,
    stdout: int | None = asyncio.subprocess.PIPE,
    stderr: int | None = asyncio.subprocess.PIPE,
    **popen,
) -> asyncio.subprocess.Process:
    """``cmd`` started from the event loop, which goes on meanwhile (a simulator in the test's own
    loop keeps serving): from this source tree as `started` starts it, its output piped unless
    told; ``popen``: further arguments of subprocess.Popen (``preexec_fn``)."""
    return await asyncio.create_subprocess_exec(*cmd, cwd=ROOT, env=child_env(), stdout=stdout, stderr=stderr, **popen)


async def orbitrig_started_async(*args: str, **kw) -> asyncio.subprocess.Process:
    """`orbitrig ARGS...` (as `python -m orbitrig`) started as `started_async` starts a command."""
    return await started_async(orbitrig_cmd(*args), **kw)


@contextlib.asynccontextmanager
async def reaped_async(proc: asyncio.subprocess.Process) -> AsyncIterator[asyncio.subprocess.Process]:
    """``proc`` (started from the event loop) for the block; after it, passed or failed, killed if
    it still runs, and waited for. A failure in the block shows what the process had left on its
    standard error pipe (the test's captured stderr), as :func:`reaped` does."""
    try:
        yield proc
    except BaseException:
        await _ended_async(proc)
        sys.stderr.write(f"standard error of process {proc.pid}:\n{(await _left_async(proc))[-5000:]}\n")
        raise
    finally:
        await _ended_async(proc)


async def _ended_async(proc: asyncio.subprocess.Process) -> None:
    if proc.returncode is None:
        proc.kill()
        await proc.wait()


async def _left_async(proc: asyncio.subprocess.Process) -> str:
    """The rest of its standard error pipe (see :func:`_left`)."""
    if proc.stderr is None:
        return ""
    try:
        return (await asyncio.wait_for(proc.stderr.read(), 5)).decode(errors="replace")
    except (TimeoutError, ValueError, OSError):
        return "(not read: the pipe is still open)"


async def orbitrig_async(*args: str, timeout: float | None = None) -> tuple[int, str, str]:
    """`orbitrig ARGS...` (as `python -m orbitrig`) run to its end from the event loop, which goes on
    meanwhile: (exit status, standard output, standard error); killed if it has not ended within
    ``timeout`` s (None: no limit) or the wait fails."""
    async with reaped_async(await orbitrig_started_async(*args)) as proc:
        out, err = await asyncio.wait_for(proc.communicate(), timeout)
    assert proc.returncode is not None
    return proc.returncode, out.decode(), err.decode()
