"""`orbitrig drives run --hold` ended by a real signal: SIGTERM, SIGHUP and SIGQUIT ramp both drives to
zero (exit 0); a second signal during that ramp makes it an emergency stop (exit 4). So they do while
its terminal does not read (the operator's Ctrl-S, through a pseudo-terminal's line discipline): what
it says waits, the stop does not."""

from __future__ import annotations

import asyncio
import signal
import time

import pytest
from support.cli_helpers import orbitrig_started_async, reaped_async
from support.drives_testkit import CW_EMERGENCY, CW_RAMP_STOP, make_models, serve, SimDrives
from support.pseudo_terminal import CTRL_Q, CTRL_S, Terminal

pytestmark = pytest.mark.timeout(60)
SW_AT_SETPOINT = 0x100


@pytest.fixture
async def slow_sim() -> SimDrives:
    """The drives with slow ramps (about a second from 1500 rpm): long enough to signal twice."""
    models = make_models(speedup=3.0)
    endpoint = await serve("tcp", models)
    try:
        yield SimDrives("tcp", models, endpoint)
    finally:
        await endpoint.aclose()


async def _hold(sim: SimDrives, terminal: Terminal | None = None, **popen):
    """`drives run --hold` at the setpoint (its output on ``terminal`` if given, else piped)."""
    out = {} if terminal is None else {"stdout": terminal.tty, "stderr": terminal.tty}
    out.update(popen)
    proc = await orbitrig_started_async(
        "drives",
        "run",
        "--modbus",
        sim.url,
        "--spin",
        "1500",
        "--orbit",
        "-750",
        "--settle",
        "0.05",
        "--timeout",
        "30",
        "--hold",
        **out,
    )
    if terminal is not None:
        terminal.started()
        await asyncio.to_thread(terminal.shows, "holding at the setpoint", 30)
        return proc
    said = b""
    while b"holding at the setpoint" not in said:  # the command's own word that it holds
        line = await asyncio.wait_for(proc.stderr.readline(), 30)
        assert line, f"exited before holding: {said.decode()}"
        said += line
    assert sim.regs(1)["SW"] & SW_AT_SETPOINT and sim.regs(2)["SW"] & SW_AT_SETPOINT
    proc.said = said.decode()  # type: ignore[attr-defined]
    return proc


async def test_a_hold_started_with_ctrl_c_ignored_names_only_the_signals_that_stop_it(slow_sim):
    """A background job of a script (`orbitrig drives run --hold &`: SIGINT ignored) never offers
    Ctrl-C, which would leave both drives turning; it says so, and SIGTERM still ends it."""
    sim = slow_sim
    proc = await _hold(sim, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    assert "note: started with SIGINT ignored (nohup, or a background job)" in proc.said
    assert "holding at the setpoint; SIGTERM, SIGHUP or SIGQUIT ramps both drives to zero" in proc.said
    proc.send_signal(signal.SIGINT)  # ignored, as it was at the start
    await asyncio.sleep(0.5)
    assert proc.returncode is None and sim.regs(1)["SW"] & SW_AT_SETPOINT
    proc.send_signal(signal.SIGTERM)
    code, err = await _finish(proc)
    assert code == 0 and "SIGTERM: ramping both drives to zero" in err, err
    await sim.wait_stopped()


async def _finish(proc) -> tuple[int, str]:
    async with reaped_async(proc):
        _, err = await asyncio.wait_for(proc.communicate(), 30)
    return proc.returncode, err.decode()


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT], ids=["SIGTERM", "SIGHUP", "SIGQUIT"])
async def test_sigterm_and_sighup_end_the_hold_with_a_ramp(slow_sim, sig):
    sim = slow_sim
    proc = await _hold(sim)
    proc.send_signal(sig)
    code, err = await _finish(proc)
    assert code == 0, err
    assert f"{sig.name}: ramping both drives to zero" in err and "Traceback" not in err
    for dev in (1, 2):
        assert sim.regs(dev)["CW"] == CW_RAMP_STOP and sim.not_the_watchdog(dev)
    await sim.wait_stopped()


async def test_a_second_signal_during_the_ramp_is_an_emergency_stop(slow_sim):
    sim = slow_sim
    proc = await _hold(sim)
    proc.send_signal(signal.SIGTERM)
    await sim.wait_for(lambda: sim.regs(1)["CW"] == CW_RAMP_STOP and sim.regs(2)["CW"] == CW_RAMP_STOP, 10, "ramp stop")
    assert sim.rpm(1) > 100  # still ramping down
    proc.send_signal(signal.SIGINT)
    code, err = await _finish(proc)
    assert code == 4, err
    assert "SIGINT; a second signal during the ramp: drives: emergency stop (OFF3)" in err
    for dev in (1, 2):
        assert sim.regs(dev)["CW"] == CW_EMERGENCY and sim.not_the_watchdog(dev)
    await sim.wait_stopped()


async def test_a_signal_ends_the_hold_while_its_terminal_does_not_read(slow_sim):
    sim, terminal, proc = slow_sim, Terminal(), None
    try:
        proc = await _hold(sim, terminal)
        terminal.press(CTRL_S)
        await asyncio.sleep(0.5)
        proc.send_signal(signal.SIGTERM)  # its words ('SIGTERM: ramping both drives to zero') meet the stopped output
        ramp = lambda: sim.regs(1)["CW"] == CW_RAMP_STOP and sim.regs(2)["CW"] == CW_RAMP_STOP  # noqa: E731
        await sim.wait_for(ramp, 5, "the ramp stop while the terminal does not read")  # before: none until Ctrl-Q
        await sim.wait_stopped()
        terminal.press(CTRL_Q)
        assert await asyncio.wait_for(proc.wait(), 30) == 0
        await asyncio.to_thread(terminal.shows, "both drives stopped", 10)
        assert all(sim.not_the_watchdog(dev) for dev in (1, 2))
    finally:
        if proc is not None and proc.returncode is None:
            proc.kill()
            await proc.wait()
        terminal.close()


async def test_ctrl_z_does_not_suspend_the_hold(slow_sim):
    """Ctrl-Z (SIGTSTP) while both drives hold is refused with a line, and the hold goes on polling
    them: before, the process was suspended and the drives turned unwatched until their comm-loss
    watchdog tripped them (fault 7510). SIGTERM still ramps both to zero."""
    sim = slow_sim
    proc = await _hold(sim)
    try:
        proc.send_signal(signal.SIGTSTP)
        said = b""
        while b"Ctrl-Z ignored" not in said:
            line = await asyncio.wait_for(proc.stderr.readline(), 10)
            assert line, f"exited after Ctrl-Z: {said.decode()}"
            said += line
        assert "Ctrl-Z ignored: orbitrig drives run does not suspend while it commands the drives" in said.decode()
        before = [sim.models[dev].last_request for dev in (1, 2)]
        await asyncio.sleep(1.0)
        assert all(sim.models[dev].last_request > t for dev, t in zip((1, 2), before))  # still polled
        assert all(sim.regs(dev)["SW"] & SW_AT_SETPOINT and sim.regs(dev)["FAULT"] == 0 for dev in (1, 2))
    finally:
        proc.send_signal(signal.SIGCONT)  # a process suspended (before) takes the SIGTERM
        proc.send_signal(signal.SIGTERM)
    code, err = await _finish(proc)
    assert code == 0 and "SIGTERM: ramping both drives to zero" in err, err
    for dev in (1, 2):
        assert sim.regs(dev)["CW"] == CW_RAMP_STOP and sim.not_the_watchdog(dev)
    await sim.wait_stopped()


async def test_a_cancel_arriving_as_the_hold_ends_is_not_lost(tcp_sim):
    """The hold's wait on its end (`Interrupt.event`) is drives.waits.first_set: a cancel in the
    loop turn the event fires gets through (asyncio.wait_for of Python 3.11 returned the event's
    result then, the hold ending as if by a signal alone, the cancel dropped)."""
    from support.drives_testkit import RPM, open_rig

    from drives.limits import DriveLimits
    from orbitrig.cli.drives_hold import Interrupt, _poll_at_setpoint

    limits = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM, min_ratio=None, max_ratio=1.0)
    async with open_rig(tcp_sim, limits) as rig:
        for _ in range(5):
            interrupt = Interrupt()
            interrupt.holding = True
            hold = asyncio.ensure_future(_poll_at_setpoint(rig, 3600.0, interrupt, time.monotonic()))
            await asyncio.sleep(0)  # the hold waits on its event
            interrupt.event.set()
            hold.cancel()
            with pytest.raises(asyncio.CancelledError):
                await hold
