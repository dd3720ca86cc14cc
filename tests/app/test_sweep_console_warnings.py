"""The operator watching `orbitrig sweep` sees the run's warnings, not only its state changes: the
A/D link dropped (the simulator's close_adc_link, through its control API, while a real `sweep
--sim` subprocess runs its first point) is one line on the sweep's standard error, with the
console's time stamp, the same words as run.log's; the routine notes (speeds set) are not there."""

from __future__ import annotations

import json
import re
import signal
import sys
import time
from pathlib import Path

import pytest

from orbitrig.cli.simulated_rig import SimulatorLink
from support.paths import ROOT
from support.store_checks import small_matrix
from support.sweep_process import SweepProcess, sweeps

pytestmark = pytest.mark.timeout(150)

SPY = ROOT / "tests" / "support" / "sim_endpoints_spy.py"
STAMPED = re.compile(r"(\[\d\d:\d\d:\d\d\]| {10}) warning: point")
LINK_LINE = re.compile(r"\] (point 0000 \[\w+\]: A/D link dropped once (?:during|before) the block[^\n]*)$")


class Sweep(SweepProcess):
    """`orbitrig sweep --sim` of a one-point matrix, its simulator's endpoints written to a file."""

    def __init__(self, work: Path):
        self.endpoints = work / "sim.json"
        self.launcher = (sys.executable, str(SPY), str(self.endpoints))
        (work / "m.toml").write_text(small_matrix("warnings", 200, spin_rpm=(1000.0,)))
        super().__init__(work / "run", "--matrix", str(work / "m.toml"), "--speedup", "5")

    def simulator(self, timeout: float = 60.0) -> SimulatorLink:
        deadline = time.monotonic() + timeout
        while not self.endpoints.exists():
            assert self.proc.poll() is None, self.proc.stderr.read()
            assert time.monotonic() < deadline, "the simulator announced no endpoints"
            time.sleep(0.01)
        return SimulatorLink(json.loads(self.endpoints.read_text())["control"])


def test_an_adc_link_drop_is_a_warning_line_on_the_sweeps_console(tmp_path):
    with sweeps(lambda: Sweep(tmp_path)) as start:
        s = start()
        sim = s.simulator()
        s.wait_log("[running] speeds set: spin 1000 rpm")
        sim.call("inject", fault="close_adc_link", reopen_after=0.2)
        s.wait_log("A/D link dropped")
        sim.close()
        s.proc.send_signal(signal.SIGTERM)  # stops at once, with a ramp
        assert s.proc.wait(60) == 3
        err = s.proc.stderr.read()
    said = [m.group(1) for line in s.text().splitlines() if (m := LINK_LINE.search(line))]
    assert len(said) == 1, s.text()
    console = " ".join(err.split())  # the console's lines as one, however the terminal wrapped them
    assert console.count(said[0]) == 1, err
    assert f"warning: {said[0]}" in console, err
    first = next(line for line in err.splitlines() if "warning: point 0000" in line)
    assert STAMPED.match(first), err  # as a state line: its time, or the one above it in the same second
    assert "speeds set" not in console and "running: " in console, err  # its state lines, no routine notes
