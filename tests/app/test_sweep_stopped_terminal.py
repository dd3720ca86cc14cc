"""A sweep whose terminal stops reading (the operator's Ctrl-S: XOFF, the output held by the
terminal's line discipline) still takes a signal at once and stops its drives itself: the run's
console is written by a thread of its own (orbitrig.cli.terminal.BackgroundStream). Before, the
first line written then held the event loop that polls the drives: no stop went out until Ctrl-Q,
and both drives tripped on their comm-loss watchdog (fault 7510). Real parts: a pseudo-terminal
and the keystrokes through its line discipline, the sweep's simulator."""

from __future__ import annotations

import os
import signal
import subprocess
import time

import pytest

from orbitrig.cli.terminal import WAITING_MAX, BackgroundStream
from support.cli_helpers import orbitrig_cmd, started
from support.pseudo_terminal import CTRL_Q, CTRL_S, Terminal
from support.store_checks import small_matrix
from support.sweep_process import SweepProcess

pytestmark = pytest.mark.timeout(120)

SAFE = "spin ACT 0 rpm, fault 0; orbit ACT 0 rpm, fault 0"


class TerminalSweep(SweepProcess):
    """`orbitrig sweep --sim` with its standard error on ``terminal``."""

    def __init__(self, out, *args: str):
        self.terminal = Terminal()
        super().__init__(out, *args)
        self.terminal.started()

    def start(self, *args: str) -> subprocess.Popen:
        command = orbitrig_cmd("sweep", "--sim", "--out", str(self.out), *args)
        tty = self.terminal.tty
        return started(command, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=tty)


def test_a_terminal_that_stops_reading_holds_back_no_stop(tmp_path):
    (tmp_path / "m.toml").write_text(small_matrix("stopped", 200, (1000.0,)))
    s = TerminalSweep(tmp_path / "run", "--matrix", str(tmp_path / "m.toml"), "--speedup", "5")
    try:
        s.wait_log("[running] speeds set: spin 1000 rpm")
        s.terminal.press(CTRL_S)
        time.sleep(1.5)  # the bars redraw 8 times a second: a write has met the stopped output
        s.proc.send_signal(signal.SIGTERM)
        s.wait_log("drives: ramp stop (OFF1); standstill after", timeout=10)  # before: nothing until Ctrl-Q
        log = s.text()
        assert "[stopping] SIGTERM: stopping now, both drives ramp to zero" in log and SAFE in log, log
        s.terminal.press(CTRL_Q)
        assert s.proc.wait(30) == 3
        assert s.status() == "stopped"
        s.terminal.shows("run stopped: stopped at once by SIGTERM", 10)  # said once the terminal reads
    finally:
        s.close()
        s.terminal.close()


def test_a_stream_nobody_reads_takes_each_write_at_once_and_drops_what_is_beyond_its_bound():
    read_end, write_end = os.pipe()
    stream = BackgroundStream(os.fdopen(write_end, "w"))
    t0 = time.monotonic()
    for _ in range(3):  # the pipe holds 64 KiB; nobody reads it
        stream.write("x" * WAITING_MAX)
    assert time.monotonic() - t0 < 1.0 and not stream.finish(0.2)
    assert stream.dropped >= WAITING_MAX
    with os.fdopen(read_end, "rb") as reader:  # read now: what was taken is written, in full
        got = 0
        while got + stream.dropped < 3 * WAITING_MAX:
            got += len(reader.read1(1 << 20))
    assert got + stream.dropped == 3 * WAITING_MAX and stream.finish(5)
