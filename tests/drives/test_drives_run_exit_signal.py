"""`orbitrig drives run` hit by a signal as it leaves: both drives have been released at the setpoint
and the rig's exit is under way when Ctrl-C arrives. The exit's stop is followed through: both
drives ramped to zero and confirmed at standstill before the command says so (exit 2); it used to
say "nothing commanded" and exit 2 at once, the drives still ramping down from 1500 rpm.

Real parts: the simulator's drives behind a real Modbus TCP server (in a thread of its own), the
command's own entry (`_run_command`, its signal handlers on this process) and a real SIGINT, sent
to this process the moment the command releases the drives (`RigDrives.release`): that is the only
hook, the few milliseconds of the exit being too short to hit from outside."""

from __future__ import annotations

import os
import signal
import time

import pytest
import typer
from drives.rig import RigDrives
from support.drives_testkit import CW_RAMP_STOP

pytestmark = pytest.mark.timeout(60)


def test_a_signal_as_run_leaves_the_drives_is_followed_to_standstill(threaded_sim, monkeypatch, capsys):
    from orbitrig.cli.drives import _run_command

    sim = threaded_sim
    release = RigDrives.release
    sent: list[float] = []

    def release_then_signal(rig: RigDrives, said=None) -> None:
        release(rig, said)
        sent.append(time.monotonic())
        os.kill(os.getpid(), signal.SIGINT)  # handled by the command's loop as the rig's exit begins

    monkeypatch.setattr(RigDrives, "release", release_then_signal)
    with pytest.raises(typer.Exit) as ended:
        _run_command(
            **dict(spin=1500.0, orbit=-750.0, modbus=sim.url, config=None, max_spin=None, max_orbit=None),
            **dict(min_ratio=None, max_ratio=None, settle=0.05, timeout=30.0, hold=False, status_every=5.0),
            **dict(spin_id=None, orbit_id=None),
        )
    took = time.monotonic() - sent[0]
    at_exit = [sim.regs(dev) for dev in (1, 2)]
    err = capsys.readouterr().err
    assert ended.value.exit_code == 2, err
    for regs in at_exit:  # read as the command returned: stopped, not still ramping
        assert regs["CW"] == CW_RAMP_STOP and regs["ACT"] == 0, (at_exit, err)
    head = "orbitrig drives run: interrupted by SIGINT as it left both drives at the setpoint; both drives stopped; "
    assert head + "drives: ramp stop (OFF1); standstill after " in err, err
    assert "nothing commanded" not in err and "Traceback" not in err, err
    assert took < 10.0, took  # the 0.8 s ramp and opening the drives again, with a busy machine's margin


def test_a_stop_after_the_release_that_cannot_open_the_drives_still_sends_the_stop_words(
    threaded_sim, monkeypatch, capsys
):
    """A signal once the command's loop has ended (the drives left at the setpoint), and the
    drives, opened again to stop them, do not answer the first reads: the stop words still go to
    each drive that answers, without reading first, as `orbitrig drives stop` does, and the message
    names those that took them (exit 1: standstill not confirmed). They used to be left at the
    setpoint with nothing sent. The signal is sent as the command's event loop shuts down."""
    import asyncio.runners

    from orbitrig.cli.drives import _run_command

    sim = threaded_sim
    close, fired = asyncio.runners.Runner.close, []

    def close_after_signal(runner) -> None:
        if not fired:
            fired.append(time.monotonic())
            sim.endpoint.drop_next(2)  # the reads of the spin drive's parameters and their retry
            os.kill(os.getpid(), signal.SIGINT)
        close(runner)

    monkeypatch.setattr(asyncio.runners.Runner, "close", close_after_signal)
    with pytest.raises(typer.Exit) as ended:
        _run_command(
            **dict(spin=1500.0, orbit=-750.0, modbus=sim.url, config=None, max_spin=None, max_orbit=None),
            **dict(min_ratio=None, max_ratio=None, settle=0.05, timeout=30.0, hold=False, status_every=5.0),
            **dict(spin_id=None, orbit_id=None),
        )
    at_exit = [sim.regs(dev) for dev in (1, 2)]
    err = capsys.readouterr().err
    assert "orbitrig drives run: WARNING: both drives left running at the setpoint" in err, err  # the exit said it
    assert ended.value.exit_code == 1, err
    assert "drives not confirmed stopped: DriveTimeoutError" in err, err
    assert "stop word delivered to: spin (id 1), orbit (id 2)" in err, err
    for regs in at_exit:  # ramping down, no longer held at the setpoint
        assert regs["CW"] == CW_RAMP_STOP and regs["REF"] == 0, (at_exit, err)
