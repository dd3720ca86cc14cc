"""Running the `orbitrig` command of this source tree as a user does (a subprocess)."""

from __future__ import annotations

import asyncio
import os
import subprocess
import sys
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


def orbitrig_in_process(*args: str) -> subprocess.CompletedProcess:
    """`orbitrig ARGS...` run in this process (typer's runner), wide terminal: the same exit status
    and output as `orbitrig` for a command that ends on its own, without an interpreter's start."""
    from typer.testing import CliRunner

    from orbitrig.cli import app

    res = CliRunner().invoke(app, list(args), env={"COLUMNS": "200", "NO_COLOR": "1"})
    if res.exception is not None and not isinstance(res.exception, SystemExit):
        raise res.exception
    return subprocess.CompletedProcess(["orbitrig", *args], res.exit_code, res.stdout, res.stderr)
