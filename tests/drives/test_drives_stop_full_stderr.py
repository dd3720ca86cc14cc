"""`orbitrig drives stop` with standard error on a full disk: the stop goes out and its exit
status says how the drives ended (3: stopped, with a rig configuration that has errors), although
neither its warning before the stop (a rig configuration not read) nor the ones after it (ids not
from that configuration, the configuration's errors) can be written.
The first one's failure ended the command before anything was sent: the drives kept turning."""

from __future__ import annotations

import subprocess
import sys

import pytest

from support.drives_testkit import CW_RAMP_STOP, CW_RUN
from support.paths import ROOT

CW_READY = 0x0476  # the spec's "ready to switch on" word


@pytest.mark.parametrize("stdout", ["devnull", "full"])
def test_a_stop_with_standard_error_full_stops_and_says_so_by_its_exit_status(threaded_tcp_sim, tmp_path, stdout):
    sim, broken = threaded_tcp_sim, tmp_path / "rig.toml"
    broken.write_text("[drives\nspin_id = 5\n")
    for dev in (1, 2):  # both turning
        for address, word in ((1, 3000), (0, CW_READY), (0, CW_RUN)):
            sim.in_loop(sim.models[dev].write, address, [word])
    cmd = [sys.executable, "-m", "orbitrig", "drives", "stop", "--modbus", sim.url, "--config", str(broken)]
    with open("/dev/full", "w") as full:
        out = full if stdout == "full" else subprocess.DEVNULL
        done = subprocess.run(cmd, cwd=ROOT, stdout=out, stderr=full, timeout=60)
    assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RAMP_STOP
    assert sim.regs(1)["ACT"] == sim.regs(2)["ACT"] == 0
    assert done.returncode == (3 if stdout == "devnull" else 2)  # its state lines lost: the drives error form, 2
