"""Every way out of `orbitrig drives run` but the release at the setpoint: both drives stopped and
confirmed at standstill before the command exits and says so; a second signal makes the stop an
emergency stop; a stop not confirmed is said ("drives not confirmed stopped", exit 1); a reader
gone from standard output (`| head -1`) ends neither the run nor the hold, a full disk behind it
ends both as a failure. Real signals to a real subprocess (standard output on /dev/full), the
drives' registers read when it exits."""

from __future__ import annotations

import asyncio
import contextlib
import os
import signal
from pathlib import Path

import pytest
from orbitrig.config import default_rig_path
from support.cli_helpers import orbitrig_started_async, reaped_async
from support.drives_testkit import CW_EMERGENCY, CW_RAMP_STOP, CW_RUN, SimDrives, exit_with_registers
from support.rig_configs import drive_lines

pytestmark = pytest.mark.timeout(60)
SW_AT_SETPOINT = 0x100


async def _run(sim: SimDrives, *extra: str, stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE):
    return await orbitrig_started_async(
        "drives",
        "run",
        "--modbus",
        sim.url,
        "--spin",
        "1500",
        "--orbit",
        "-750",
        "--timeout",
        "30",
        *extra,
        stdout=stdout,
        stderr=stderr,
    )


def _short_watchdog(tmp_path: Path) -> str:
    """The tests' lab rig.toml (the patient link) with a 4 s drive watchdog, the link lost after
    4 x (0.1 + 0.6) s = 2.8 s (below 0.8 x 4 s): a drive held by its keypad is starved of requests
    until its watchdog would have tripped (4.7 s, not the 10.7 s of the lab's 10 s) before the
    command exits."""
    changes = (
        ("timeout_s = 1.0", "timeout_s = 0.6"),
        ("link_loss_polls = 5", "link_loss_polls = 4"),
        ("comm_loss_timeout_s = 10.0", "comm_loss_timeout_s = 4.0"),
    )
    text = drive_lines(default_rig_path().read_text(), changes)
    path = tmp_path / "rig.toml"
    path.write_text(text)
    return str(path)


def _at_setpoint(sim: SimDrives) -> bool:
    return bool(sim.regs(1)["SW"] & SW_AT_SETPOINT and sim.regs(2)["SW"] & SW_AT_SETPOINT)


def _ramping(sim: SimDrives) -> bool:
    return sim.regs(1)["CW"] == CW_RAMP_STOP and sim.regs(2)["CW"] == CW_RAMP_STOP


async def test_a_second_signal_during_the_ramp_is_an_emergency_stop(slow_drives):
    sim = slow_drives
    proc = await _run(sim, "--settle", "30")
    await sim.wait_for(lambda: _at_setpoint(sim), 20, "at setpoint")
    proc.send_signal(signal.SIGTERM)
    await sim.wait_for(lambda: _ramping(sim), 10, "ramp stop")
    assert sim.rpm(1) > 300  # still ramping down
    proc.send_signal(signal.SIGQUIT)
    code, err, at_exit = await exit_with_registers(proc, sim)
    assert code == 4, err
    assert (
        "interrupted by SIGTERM; both drives stopped; SIGQUIT; a second signal during the stop: drives: emergency stop (OFF3)"
        in err
    )
    for regs in at_exit:
        assert regs["CW"] == CW_EMERGENCY and regs["ACT"] == 0, at_exit


async def test_a_stop_not_confirmed_is_said_and_fails(slow_drives, tmp_path):
    """The spin drive taken over by its keypad after the stop word and held there (a drive in local
    control that ignores network words; the simulator's takes one with REMOTE = 1 back, so the
    keypad is pressed again every 10 ms): the stop sent again does not stop it, no standstill to
    confirm."""
    sim = slow_drives
    proc = await _run(sim, "--settle", "30", "--config", _short_watchdog(tmp_path))
    await _interrupted_at_setpoint(sim, proc)
    async with _keypad_holds_the_spin_drive(sim):
        code, err, _ = await exit_with_registers(proc, sim)
    assert code == 1, err
    assert "interrupted by SIGINT; drives not confirmed stopped: DriveTimeoutError" in err
    assert "both drives stopped" not in err and "Traceback" not in err


async def test_the_hold_outlives_a_closed_standard_output(slow_drives):
    """`drives run --hold | head -1`: the hold goes on once the reader is gone; a signal then
    ends it with both drives at standstill when the command exits."""
    sim = slow_drives
    r, w = os.pipe()
    try:
        proc = await _run(sim, "--settle", "0.05", "--hold", "--status-every", "0.1", stdout=w)
    finally:
        os.close(w)
    first = await asyncio.get_running_loop().run_in_executor(None, os.read, r, 4096)
    assert first.startswith(b"spin  (id 1): running, at setpoint"), first
    os.close(r)  # `head -1` has its line and exits
    await asyncio.sleep(1.0)  # several status lines written into the broken pipe meanwhile
    assert proc.returncode is None, (await proc.stderr.read()).decode()
    assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RUN and _at_setpoint(sim)
    proc.send_signal(signal.SIGTERM)
    code, err, at_exit = await exit_with_registers(proc, sim)
    assert code == 0, err
    assert "SIGTERM: ramping both drives to zero" in err and "Traceback" not in err
    for regs in at_exit:
        assert regs["CW"] == CW_RAMP_STOP and regs["ACT"] == 0, at_exit


async def test_run_to_a_closed_standard_output_still_reaches_its_setpoint(slow_drives):
    """`drives run | head -1` with the reader gone at once: the run is not failed by its own
    output (exit 0, the drives left at their setpoint as documented)."""
    sim = slow_drives
    r, w = os.pipe()
    os.close(r)
    try:
        proc = await _run(sim, "--settle", "0.05", stdout=w)
    finally:
        os.close(w)
    code, err, at_exit = await exit_with_registers(proc, sim)
    assert code == 0, err
    assert "both drives left running at the setpoint" in err and "Traceback" not in err
    assert err.count("left running") == 1, err
    for regs in at_exit:
        assert regs["CW"] == CW_RUN and regs["SW"] & SW_AT_SETPOINT, at_exit


@pytest.mark.parametrize("hold", [False, True], ids=["run", "hold"])
async def test_a_full_disk_on_standard_output_stops_both_drives_before_the_command_fails(slow_drives, hold):
    """`drives run > file` on a full disk (/dev/full: ENOSPC): the command fails (exit 2) with both
    drives ramped to zero and confirmed at standstill, as on any failure. Without --hold it left
    them running at the setpoint and then failed on its output (the status lines were written by
    the output's thread after the release)."""
    sim = slow_drives
    full = os.open("/dev/full", os.O_WRONLY)
    try:
        extra = ("--hold", "--status-every", "0.1") if hold else ()
        proc = await _run(sim, "--settle", "0.05", *extra, stdout=full)
    finally:
        os.close(full)
    code, err, at_exit = await exit_with_registers(proc, sim)
    assert code == 2, err
    assert "error (output): standard output: No space left on device; both drives stopped" in err, err
    assert "left running" not in err and "Traceback" not in err, err
    for regs in at_exit:
        assert regs["CW"] == CW_RAMP_STOP and regs["ACT"] == 0, at_exit


async def test_a_full_disk_behind_standard_error_as_the_drives_are_left_at_the_setpoint_stops_them(slow_drives):
    """`drives run 2> file` on a full disk: its warning that the drives run on at the setpoint
    (written as the rig's exit leaves them there) cannot be written; the command fails (exit 2)
    and, as exit 2 says, both drives are ramped to zero and at standstill when it exits. It
    exited 2 with both drives running at the setpoint."""
    sim = slow_drives
    proc = await _run_to_a_full_disk(sim, "--settle", "0.05")
    async with reaped_async(proc):
        out, _ = await asyncio.wait_for(proc.communicate(), 40)
        at_exit = [sim.regs(dev) for dev in (1, 2)]
    assert proc.returncode == 2, out
    assert out.decode().startswith("spin  (id 1): running, at setpoint"), out
    for regs in at_exit:
        assert regs["CW"] == CW_RAMP_STOP and regs["ACT"] == 0, at_exit


async def test_a_stop_not_confirmed_with_a_full_disk_behind_standard_error_still_exits_1(slow_drives, tmp_path):
    """`drives run 2> file` on a full disk and the stop not confirmed (the spin drive held by its
    keypad, as above): the line saying so cannot be written, and the exit status still says that
    the drives are not known stopped (1), not the 2 of a failure with both stopped that the
    output's failure gave it."""
    sim = slow_drives
    proc = await _run_to_a_full_disk(sim, "--settle", "30", "--config", _short_watchdog(tmp_path))
    await _interrupted_at_setpoint(sim, proc)
    async with _keypad_holds_the_spin_drive(sim), reaped_async(proc):
        await asyncio.wait_for(proc.communicate(), 40)
    assert proc.returncode == 1


async def _interrupted_at_setpoint(sim, proc) -> None:
    """``proc`` (a `drives run`) interrupted once both drives are at their setpoint, its ramp stop seen."""
    await sim.wait_for(lambda: _at_setpoint(sim), 20, "at setpoint")
    proc.send_signal(signal.SIGINT)
    await sim.wait_for(lambda: _ramping(sim), 10, "ramp stop")


@contextlib.asynccontextmanager
async def _keypad_holds_the_spin_drive(sim):
    """The spin drive taken over by its keypad every 10 ms while the block runs (the simulator's
    drive takes one with REMOTE = 1 back): the network's stop words do not stop it."""

    async def keypad() -> None:
        while True:
            sim.models[1].local_control(1000.0)
            await asyncio.sleep(0.01)

    held = asyncio.ensure_future(keypad())
    try:
        yield
    finally:
        held.cancel()


async def _run_to_a_full_disk(sim, *args: str):
    """`drives run ARGS 2> file` on a full disk (standard error on /dev/full), started."""
    full = os.open("/dev/full", os.O_WRONLY)
    try:
        return await _run(sim, *args, stderr=full)
    finally:
        os.close(full)
