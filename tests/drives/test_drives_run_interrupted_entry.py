"""`orbitrig drives run` interrupted while it opens the drives (its rig's entry, which lets go of
its link at once when cancelled): the drives found turning are not left to their own watchdog.
The ramp stop words (OFF1) go to each drive that answers, over a link of the command's own; a
second signal meanwhile makes them the emergency stop (OFF3), exit 4; the message names the
drives that took theirs, exit 2.

The simulator's drives behind Modbus TCP, left turning with their comm-loss watchdog off (only a
stop word the command delivers stops them). The orbit drive's requests go unanswered while the
entry reads it, so the signal lands there (each request for it is watched at the server)."""

from __future__ import annotations

import asyncio
import signal
import time

import pytest
from support.cli_helpers import orbitrig_started_async, reaped_async
from support.drives_testkit import CW_EMERGENCY, CW_RAMP_STOP, CW_RUN, RPM, SimDrives, open_rig

from drives.limits import DriveLimits
from orbitrig.cli.drives_hold import Interrupt
from orbitrig.run.stop_words import StopWordsSent

pytestmark = pytest.mark.timeout(60)


async def _left_running(sim: SimDrives) -> None:
    """Both drives left turning by a client gone away, their comm-loss watchdog off."""
    limits = DriveLimits(2400 * RPM, 2400 * RPM)
    async with open_rig(sim, limits, comm_loss_timeout=0.0, timeout=1.0) as rig:  # 1 s: nothing is to go unanswered
        await rig.set_speeds(1200 * RPM, 600 * RPM)
        await rig.wait_settled(hold=0.1, timeout=20)
        rig.release()
    assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RUN and sim.regs(1)["ACT"] > 0


class _OrbitSilent:
    """The orbit drive (id 2) left unanswered while `silent`; `asked[n]` set at its (n+1)th
    request since (answered or not)."""

    def __init__(self, sim: SimDrives, monkeypatch) -> None:
        self.silent = True
        self.asked = [asyncio.Event() for _ in range(8)]
        self._seen = 0
        gate = sim.endpoint._gate  # the server's request filter: no public hook sees each request
        admit = gate.admit

        def spy(dev_id: int) -> bool:
            if dev_id == 2:
                if self._seen < len(self.asked):
                    self.asked[self._seen].set()
                self._seen += 1
                if self.silent:
                    return False
            return admit(dev_id)

        monkeypatch.setattr(gate, "admit", spy)


async def _run_signalled(sim: SimDrives, moments) -> tuple[int, str, float]:
    """`drives run` at 300/100 rpm, SIGINT after each awaited ``moments()``; (exit code, stderr,
    wall s from the first signal to the exit)."""
    proc = await orbitrig_started_async("drives", "run", "--modbus", sim.url, "--spin", "300", "--orbit", "100")
    t_signal = None
    async with reaped_async(proc):
        for moment in moments:
            await moment()
            t_signal = t_signal or time.monotonic()
            proc.send_signal(signal.SIGINT)
        _, err = await asyncio.wait_for(proc.communicate(), 30)
    assert proc.returncode is not None and t_signal is not None
    return proc.returncode, err.decode(), time.monotonic() - t_signal


async def test_sigint_while_run_opens_the_drives_ramps_the_turning_drives_to_zero(tcp_sim, monkeypatch):
    sim = tcp_sim
    await _left_running(sim)
    orbit = _OrbitSilent(sim, monkeypatch)
    t0 = time.monotonic()

    async def entry_reads_orbit() -> None:
        await asyncio.wait_for(orbit.asked[0].wait(), 20)  # the entry's read of its parameters
        orbit.silent = False  # it answers again: the stop word reaches it

    code, err, took = await _run_signalled(sim, [entry_reads_orbit])
    assert code == 2, err
    line = (
        "orbitrig drives run: interrupted by SIGINT while opening the drives; ramp stop (OFF1) sent; "
        "stop word delivered to: spin (id 1), orbit (id 2)\n"
    )
    assert line in err, err
    assert "nothing commanded" not in err and "Traceback" not in err, err
    for dev in (1, 2):  # the ramp stop word, and no other, since the command began
        words = {cw for t, cw in sim.models[dev].control_words if t >= t0}
        assert words == {CW_RAMP_STOP}, (dev, words)
    assert took < 5.0, took  # no hang: the stop words at once (a request timeout is 1 s here)
    await sim.wait_stopped(10.0)


async def test_second_sigint_during_the_stop_words_makes_them_the_emergency_stop(tcp_sim, monkeypatch):
    sim = tcp_sim
    await _left_running(sim)
    orbit = _OrbitSilent(sim, monkeypatch)

    async def entry_reads_orbit() -> None:
        await asyncio.wait_for(orbit.asked[0].wait(), 20)

    async def stop_word_to_orbit() -> None:
        # (its 2nd request: the status read before the ramp stop, unanswered: not read)
        await asyncio.wait_for(orbit.asked[2].wait(), 20)  # its ramp stop word, unanswered
        assert sim.regs(1)["CW"] == CW_RAMP_STOP  # the spin drive took its own first
        orbit.silent = False  # its retry is answered

    code, err, _ = await _run_signalled(sim, [entry_reads_orbit, stop_word_to_orbit])
    assert code == 4, err
    line = (
        "orbitrig drives run: interrupted by SIGINT while opening the drives; SIGINT during the ramp stop: "
        "emergency stop (OFF3) sent; stop word delivered to: spin (id 1), orbit (id 2)\n"
    )
    assert line in err, err
    assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_EMERGENCY
    await sim.wait_stopped(10.0)


@pytest.mark.parametrize(
    ("emergency", "escalated", "signals", "said"),
    [
        (False, False, ["SIGINT"], "ramp stop (OFF1) sent"),
        (True, True, ["SIGINT", "SIGTERM"], "SIGTERM during the ramp stop: emergency stop (OFF3) sent"),
        # both signals came before the words went out: no ramp stop was sent to be made an emergency stop
        (True, False, ["SIGINT", "SIGINT"], "SIGINT: emergency stop (OFF3) sent"),
    ],
)
def test_the_stop_words_say_what_went_out(emergency, escalated, signals, said):
    interrupt = Interrupt([getattr(signal.Signals, s) for s in signals])
    assert StopWordsSent(["spin (id 1)"], emergency, escalated).said(interrupt) == said
