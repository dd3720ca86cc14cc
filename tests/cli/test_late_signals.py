"""Signals once a command's event loop has handed them over (orbitrig.cli.signals.hand_over):
the first two are recorded for the command to act on, the third in a row ends the process as
Python's default would, so a process held at its exit (a stalled disk) can still be interrupted.
Real signals to a real subprocess."""

from __future__ import annotations

import signal
import subprocess
import sys

import pytest
from support.paths import ROOT

pytestmark = pytest.mark.timeout(60)

_HELD_AT_EXIT = """
import asyncio, os, signal, sys, time
from orbitrig.cli.signals import SIGNALS, hand_over, take_late_signals

async def main():
    loop = asyncio.get_running_loop()
    for sig in SIGNALS:
        loop.add_signal_handler(sig, lambda: None)
    hand_over(loop)

asyncio.run(main())
sig = signal.Signals[sys.argv[1]]
os.kill(os.getpid(), sig)
os.kill(os.getpid(), sig)
print("recorded", [s.name for s in take_late_signals()], flush=True)
os.kill(os.getpid(), sig)
os.kill(os.getpid(), sig)
print("held", flush=True)
os.kill(os.getpid(), sig)  # the third in a row
time.sleep(30)
print("not interrupted", flush=True)
"""


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_the_third_late_signal_in_a_row_ends_the_process(sig):
    proc = subprocess.run(
        [sys.executable, "-c", _HELD_AT_EXIT, sig.name], cwd=ROOT, capture_output=True, text=True, timeout=40
    )
    assert proc.stdout.splitlines() == [f"recorded ['{sig.name}', '{sig.name}']", "held"], proc.stdout
    assert proc.returncode == -sig, (
        proc.returncode,
        proc.stderr,
    )  # Ctrl-C: KeyboardInterrupt, then Python's exit by it
    assert ("KeyboardInterrupt" in proc.stderr) == (sig == signal.SIGINT), proc.stderr
