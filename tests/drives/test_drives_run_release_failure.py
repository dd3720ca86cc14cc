"""`orbitrig drives run` without --hold says once that it left both drives at the setpoint (the
rig's exit says it, with their watchdog's seconds); if the poll finds a failure as the command
leaves them there (a trip: it stops both), it does not say so: the exit stops them again, the
command opens them again, confirms standstill and fails naming the drive (exit 2).

Real parts: the simulator's drives behind a real Modbus TCP server (in a thread of its own), the
command's own entry (`_run_command`); the trip is the simulator's own, injected once the command
has released the drives, and the command's exit waits for the poll to find it (the one hook: the
exit's few milliseconds are too short to hit otherwise)."""

from __future__ import annotations

import asyncio

import pytest
import typer
from support.drives_testkit import CW_RAMP_STOP, wait_until

pytestmark = pytest.mark.timeout(60)

ARGS = dict(spin=1500.0, orbit=-750.0, config=None, max_spin=None, max_orbit=None, min_ratio=None, max_ratio=None)
RUN = dict(settle=0.05, timeout=30.0, hold=False, status_every=5.0, spin_id=None, orbit_id=None)


def test_a_trip_as_run_leaves_the_drives_is_not_said_left_running(threaded_sim, monkeypatch, capsys):
    import orbitrig.cli.drives as cli
    import orbitrig.cli.drives_run as drives_run

    sim, release = threaded_sim, drives_run._release

    async def release_then_trip(rig, wanted: float) -> None:
        await release(rig, wanted)
        sim.in_loop(sim.models[2].inject_fault, 2310)  # overcurrent at the orbit drive
        await wait_until(lambda: rig._poll.failure is not None, 5, "the trip found by the poll")
        await asyncio.sleep(0)

    monkeypatch.setattr(drives_run, "_release", release_then_trip)
    with pytest.raises(typer.Exit) as ended:
        cli._run_command(modbus=sim.url, **ARGS, **RUN)
    at_exit = [sim.regs(dev) for dev in (1, 2)]
    err = capsys.readouterr().err
    assert ended.value.exit_code == 2, err
    assert "left running" not in err, err
    head = "orbitrig drives run: error (fault): as it left both drives at the setpoint: orbit drive (id 2), register "
    assert head + "FAULT (6), fault 2310 (overcurrent): tripped; both drives stopped; " in err, err
    assert at_exit[0]["CW"] == CW_RAMP_STOP and all(regs["ACT"] == 0 for regs in at_exit), at_exit
    assert "Traceback" not in err, err


def test_a_full_disk_behind_standard_error_fails_run_whatever_the_log_is_told(threaded_sim, monkeypatch, tmp_path):
    """`drives run 2> file` on a full disk (/dev/full) in a process whose log has handlers of its own
    (here pytest's: none on standard error): the warning that the drives run on at the setpoint is
    written by the terminal's writer, not the log, so its failure is the command's (exit 2) and both
    drives are stopped first. It went to the log: nothing failed, exit 0, both left running."""
    import sys

    import orbitrig.cli.drives as cli

    sim, out = threaded_sim, tmp_path / "out.txt"
    with open(out, "w") as stdout, open("/dev/full", "w") as full:
        monkeypatch.setattr(sys, "stdout", stdout)
        monkeypatch.setattr(sys, "stderr", full)
        with pytest.raises(typer.Exit) as ended:
            cli._run_command(modbus=sim.url, **ARGS, **RUN)
        at_exit = [sim.regs(dev) for dev in (1, 2)]
        monkeypatch.undo()
    assert ended.value.exit_code == 2, out.read_text()
    assert out.read_text().startswith("spin  (id 1): running, at setpoint"), out.read_text()
    for regs in at_exit:
        assert regs["CW"] == CW_RAMP_STOP and regs["ACT"] == 0, at_exit
