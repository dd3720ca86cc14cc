"""`orbitrig sweep --sim` in a subprocess, as an operator's terminal runs it: its standard input a
pipe kept open (nobody answers unless the test writes), watched through its run.log; real
signals are sent to it (`proc.send_signal`)."""

from __future__ import annotations

import contextlib
import subprocess
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import h5py

from support.cli_helpers import ended, orbitrig_cmd, started


class SweepProcess:
    """`orbitrig sweep --sim --out OUT ARGS` started at once (behind `launcher`, e.g. ("nohup",)),
    ``env`` added to its environment."""

    launcher: tuple[str, ...] = ()

    def __init__(self, out: Path, *args: str, env: dict[str, str] | None = None):
        self.out = out
        self.log = out / "run.log"
        self.env = env
        self.proc = self.start(*args)

    def start(self, *args: str) -> subprocess.Popen:
        """Another `sweep --sim --out OUT ARGS` (a resume, say) on the same run directory."""
        command = [*self.launcher, *orbitrig_cmd("sweep", "--sim", "--out", str(self.out), *args)]
        return started(command, env=self.env, stdin=subprocess.PIPE)

    def text(self) -> str:
        return self.log.read_text() if self.log.exists() else ""

    def wait_log(self, what: str, timeout: float = 60.0) -> None:
        deadline = time.monotonic() + timeout
        while what not in self.text():
            if self.proc.poll() is not None:
                raise AssertionError(f"sweep exited {self.proc.returncode} before {what!r}:\n{self.proc.stderr.read()}")
            assert time.monotonic() < deadline, f"no {what!r} in run.log:\n{self.text()}"
            time.sleep(0.005)

    def status(self) -> str:
        """run.h5's status."""
        with h5py.File(self.out / "run.h5", "r") as f:
            return str(f.attrs["status"])

    def close(self) -> None:
        ended(self.proc)


@contextlib.contextmanager
def sweeps(make: Callable[..., SweepProcess]) -> Iterator[Callable[..., SweepProcess]]:
    """A test's `sweep(*extra)` starting ``make(*extra)``; every one started is killed at the end
    if it still runs."""
    made: list[SweepProcess] = []

    def start(*extra: str) -> SweepProcess:
        made.append(make(*extra))
        return made[-1]

    try:
        yield start
    finally:
        for s in made:
            s.close()
