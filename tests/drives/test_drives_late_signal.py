"""A signal once a drive command's event loop has ended, before the process exits.

It used to fall to Python's default handling: SIGTERM killed `orbitrig drives run` with its
drives left at the setpoint and no word said, Ctrl-C raised a KeyboardInterrupt traceback (exit
status of a killed process). Now `run`, which left the drives running, opens them again, ramps
both to zero and confirms them at standstill (exit 2); a command whose way out has stopped the
drives already exits with its own status.

Real parts: the simulator's drives behind a real Modbus TCP server, the command in a subprocess,
a real signal. The one hook: the subprocess sends the signal to itself as its event loop shuts
down (asyncio's Runner.close, after the command's coroutine has returned), a window of a few
milliseconds that cannot be hit from outside."""

from __future__ import annotations

import signal
import sys

import pytest
from support.cli_helpers import started_async
from support.drives_testkit import CW_RAMP_STOP, CW_RUN, SimDrives, exit_with_registers

pytestmark = pytest.mark.timeout(60)

#: `python -m orbitrig` with the first event loop's shutdown sending `sig` to this process
_SIGNAL_AT_LOOP_END = """
import asyncio.runners, os, signal, sys
close, fired, sig = asyncio.runners.Runner.close, [], signal.Signals[sys.argv.pop(1)]
def close_after_signal(self):
    if not fired:
        fired.append(1)
        os.kill(os.getpid(), sig)
    close(self)
asyncio.runners.Runner.close = close_after_signal
sys.argv[0] = "orbitrig"
from orbitrig.cli import main
main()
"""


async def _late_signal(sim: SimDrives, sig: signal.Signals, *command: str) -> tuple[int, str, list[dict]]:
    """(exit status, standard error, both drives' registers as it exited) of `orbitrig COMMAND
    --modbus URL`, sent `sig` as its event loop ends."""
    proc = await started_async([sys.executable, "-c", _SIGNAL_AT_LOOP_END, sig.name, *command, "--modbus", sim.url])
    return await exit_with_registers(proc, sim)


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
async def test_a_signal_after_run_left_the_drives_running_stops_them(tcp_sim, sig):
    code, err, at_exit = await _late_signal(tcp_sim, sig, "drives", "run", "--spin", "1500", "--orbit", "-750")
    assert "both drives left running at the setpoint" in err, err  # the release happened first
    assert code == 2, err
    for regs in at_exit:  # stopped and at standstill as the command exited, not left turning
        assert regs["CW"] == CW_RAMP_STOP and regs["ACT"] == 0, (at_exit, err)
    head = f"orbitrig drives run: interrupted by {sig.name} as it left both drives at the setpoint; "
    assert head + "both drives stopped; drives: ramp stop (OFF1); standstill after " in err, err
    assert "Traceback" not in err, err


async def test_a_signal_after_stop_ended_keeps_its_exit_status(tcp_sim):
    """The drives stopped by the command already: its own exit status, no traceback."""
    sim = tcp_sim
    for dev in (1, 2):
        sim.models[dev].write(0, [CW_RUN])
    code, err, at_exit = await _late_signal(sim, signal.SIGINT, "drives", "stop")
    assert code == 0 and "Traceback" not in err, err
    for regs in at_exit:
        assert regs["CW"] == CW_RAMP_STOP and regs["ACT"] == 0, at_exit
