"""Running the `orbitrig` command of this source tree as a user does: a subprocess, or in this process for a command that starts no process."""

from __future__ import annotations

import asyncio
import contextlib
import os
import subprocess
import sys
import warnings
from pathlib import Path

from .paths import ROOT


def orbitrig_cmd(*args: str) -> list[str]:
    """The command line of `orbitrig ARGS...` of this source tree (`python -m orbitrig`)."""
    return [sys.executable, "-m", "orbitrig", *args]


def orbitrig(*args: str, timeout: float = 120, cwd: Path = ROOT, **kw) -> subprocess.CompletedProcess:
    """`orbitrig ARGS...` (as `python -m orbitrig`), output captured as text, wide terminal."""
    env = {**os.environ, "COLUMNS": "200", "NO_COLOR": "1"}
    return subprocess.run(
        orbitrig_cmd(*args),
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
        stdin=subprocess.DEVNULL,
        **kw,
    )


def orbitrig_started(*args: str, cwd: Path = ROOT, stdin: int = subprocess.DEVNULL) -> subprocess.Popen:
    """`orbitrig ARGS...` started (as `python -m orbitrig`) for a test to signal, read or kill: its
    output on text pipes, its standard input closed unless `stdin` says otherwise."""
    return subprocess.Popen(
        orbitrig_cmd(*args), cwd=cwd, stdin=stdin, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )


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


async def orbitrig_async(*args: str) -> tuple[int, str, str]:
    """`orbitrig ARGS...` (as `python -m orbitrig`) run from the event loop, which goes on meanwhile
    (a simulator in the test's own loop keeps serving): (exit status, standard output, standard error)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = await asyncio.create_subprocess_exec(
        *orbitrig_cmd(*args), stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE, cwd=ROOT, env=env
    )
    out, err = await proc.communicate()
    assert proc.returncode is not None
    return proc.returncode, out.decode(), err.decode()
