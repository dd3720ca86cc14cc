"""Heartbeat, communication loss and link loss against the simulator's drives.

The drives' comm-loss watchdog runs in wall time (COMM_LOSS_TIMEOUT 0.5 s here).
"""

from __future__ import annotations

import asyncio
import logging
import re
import signal
import sys

import pytest
from support.cli_helpers import started_async
from support.drives_testkit import CW_RAMP_STOP, CW_RUN, RPM, open_rig, wait_until

from drives.errors import DriveFaultError, DriveLinkError, DriveTimeoutError
from drives.limits import DriveLimits
from drives.rig import RigDrives
from sim import drive_registers as sim_registers
from sim.modbus_server import serve_modbus_tcp

pytestmark = pytest.mark.timeout(30)  # a hang fails fast, with a traceback

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM)


def rig(sim, **kw) -> RigDrives:
    return open_rig(sim, LIMITS, **kw)


async def test_poll_keeps_the_watchdog_fed_while_the_caller_waits(sim):
    async with rig(sim) as r:
        await r.set_speeds(1000 * RPM, -500 * RPM)
        await r.wait_settled(hold=0.05, timeout=5)
        polls = r.state.polls
        await asyncio.sleep(1.2)  # more than twice COMM_LOSS_TIMEOUT doing something else
        assert r.state.polls - polls >= 15  # 24 expected at 0.05 s
        for dev in (1, 2):
            assert sim.regs(dev)["FAULT"] == 0 and sim.regs(dev)["CW"] == CW_RUN
        assert r.state.at_setpoint and r.state.link_ok


CLIENT = """
import asyncio, sys
from drives.limits import DriveLimits
from drives.rig import RigDrives

async def main():
    async with RigDrives(sys.argv[1], DriveLimits(1000.0, 1000.0), poll_interval=0.05,
                         timeout=0.3, comm_loss_timeout=0.5) as rig:
        await rig.set_speeds(150.0, -100.0)
        await rig.wait_settled(hold=0.05, timeout=10)
        print("settled", flush=True)
        await asyncio.sleep(60)

asyncio.run(main())
"""


async def test_drives_stop_by_themselves_when_the_client_dies(sim):
    proc = await started_async([sys.executable, "-c", CLIENT, sim.url], stderr=None)
    try:
        line = await asyncio.wait_for(proc.stdout.readline(), 15)
        assert line == b"settled\n"
        await asyncio.sleep(0.3)
        assert sim.regs(1)["FAULT"] == 0 and sim.rpm(1) == pytest.approx(150 / RPM, abs=5)
    finally:
        proc.send_signal(signal.SIGKILL)  # no cleanup code runs in the client
        await proc.wait()
    took = await sim.wait_for(lambda: sim.regs(1)["FAULT"] == 7510 and sim.regs(2)["FAULT"] == 7510, 3, "fault 7510")
    assert took > 0.2  # the watchdog, 0.5 s after the last request
    await sim.wait_stopped(timeout=3)
    # no stop command reached them: they stopped on their own
    assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RUN


async def test_short_link_loss_is_reported_and_the_run_goes_on(sim):
    async with rig(sim, comm_loss_timeout=2.0) as r:
        await r.set_speeds(1000 * RPM, 500 * RPM)
        await r.wait_settled(hold=0.05, timeout=5)
        sim.endpoint.set_unresponsive(True)
        await wait_until(lambda: not r.state.link_ok, 2, "link loss reported")
        assert "no answer" in r.state.link_error
        with pytest.raises(DriveLinkError, match="nothing commanded"):
            await r.set_speeds(1100 * RPM, 500 * RPM)
        await asyncio.sleep(0.1)
        sim.endpoint.set_unresponsive(False)
        st = await r.wait_settled(hold=0.1, timeout=5)  # after reconnect + verification
        assert st.link_ok and st.link_losses == 1
        # TCP reconnects; an RTU line stays open through timeouts (it settles instead)
        assert r.link.connects >= (2 if sim.kind == "tcp" else 1)
        for dev, rpm in ((1, 1000), (2, 500)):
            assert sim.regs(dev)["FAULT"] == 0 and sim.rpm(dev) == pytest.approx(rpm, abs=5)


async def test_a_drive_taken_to_local_control_while_the_link_was_down_fails_the_verification(tcp_sim, caplog):
    """The spin drive taken to its keypad while the link is down, at the commanded speed (REF and
    RDY_REF as before, SW REMOTE = 0): the reconnect's verification finds it, stops both and says
    so as the link loss's; before, it logged "both drives verified" and left it to the next check."""
    sim = tcp_sim
    async with rig(sim, comm_loss_timeout=2.0) as r:
        await r.set_speeds(1000 * RPM, 500 * RPM)
        await r.wait_settled(hold=0.05, timeout=5)
        sim.endpoint.set_unresponsive(True)
        await wait_until(lambda: not r.state.link_ok, 2, "link loss reported")
        ref = sim.regs(1)["REF"]
        sim.keypad_run(1, 1000.0)  # someone at the drive, same speed, handed back
        assert sim.regs(1)["REF"] == ref and sim.rpm(1) == pytest.approx(1000, abs=5)  # REF as commanded
        sim.endpoint.set_unresponsive(False)
        with caplog.at_level(logging.WARNING, logger="drives.poll"):
            with pytest.raises(DriveLinkError) as info:
                await r.wait_settled(hold=0.05, timeout=5)
        err = info.value
        assert (err.drive, err.register) == (1, sim_registers.SW), str(err)
        assert "link was down" in str(err) and "local control (SW REMOTE = 0" in str(err), str(err)
        assert "both drives verified" not in caplog.text
        assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RAMP_STOP
        await sim.wait_stopped(timeout=3)


async def test_link_loss_longer_than_the_watchdog(sim):
    async with rig(sim) as r:
        await r.set_speeds(1500 * RPM, -1000 * RPM)
        await r.wait_settled(hold=0.05, timeout=5)
        sim.endpoint.set_unresponsive(True)
        # the drives' own watchdog stops them
        await sim.wait_for(lambda: sim.regs(1)["FAULT"] == 7510 and sim.regs(2)["FAULT"] == 7510, 3, "7510")
        await sim.wait_stopped(timeout=3)
        assert not r.state.link_ok
        sim.endpoint.set_unresponsive(False)
        with pytest.raises(DriveFaultError, match="while the link was down") as info:
            await r.wait_settled(hold=0.05, timeout=5)
        assert info.value.fault_code == 7510
        assert r.state.link_ok and r.state.link_losses == 1
        # verified after the reconnect and commanded to stop before going on
        assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RAMP_STOP
        await r.reset_faults()
        await r.set_speeds(500 * RPM, 200 * RPM)
        await r.wait_settled(hold=0.05, timeout=5)
        assert sim.rpm(1) == pytest.approx(500, abs=5)


async def test_server_restart_reconnects(tcp_sim):
    sim = tcp_sim
    async with rig(sim, comm_loss_timeout=2.0) as r:
        await r.set_speeds(800 * RPM, 400 * RPM)
        await r.wait_settled(hold=0.05, timeout=5)
        port = sim.endpoint.port
        await sim.endpoint.aclose()
        await wait_until(lambda: not r.state.link_ok, 2, "link loss reported")
        assert "link failure" in r.state.link_error or "connect" in r.state.link_error
        sim.endpoint = await serve_modbus_tcp(sim.models, port=port)
        st = await r.wait_settled(hold=0.1, timeout=5)
        assert st.link_ok and st.link_losses == 1
        assert sim.rpm(1) == pytest.approx(800, abs=5)


class StateWatch:
    """Samples `rig.state` every 5 ms as the sweep's interlock check does:
    did the link ever read as lost, did any interlock that fails a run fire?"""

    def __init__(self, r: RigDrives):
        self.r = r
        self.ever_lost = False
        self.trips: set[str] = set()
        self._task = asyncio.create_task(self._run())

    async def _run(self):
        from orbitrig.run import interlocks as interlocks
        from orbitrig.config import Interlocks

        cfg = Interlocks()
        while True:
            self.ever_lost |= not self.r.state.link_ok
            for trip in interlocks.check(None, self.r.state, cfg, pressure_armed=False):
                self.trips.add(f"{trip.kind}:{trip.action}")
            await asyncio.sleep(0.005)

    def stop(self):
        self._task.cancel()


async def test_isolated_failed_polls_are_counted_not_a_link_loss(sim):
    """An unresponsive window shorter than link_loss_polls polls: the run goes on."""
    async with rig(sim, link_loss_polls=3) as r:
        await r.set_speeds(1000 * RPM, -500 * RPM)
        await r.wait_settled(hold=0.05, timeout=5)
        assert r.state.poll_failures == 0
        watch = StateWatch(r)
        try:
            sim.endpoint.set_unresponsive(True)
            await wait_until(lambda: r.state.poll_failures >= 1, 2, "a failed poll")
            sim.endpoint.set_unresponsive(False)  # one poll lost (0.1 s timeout): < 3 polls
            polls = r.state.polls
            await wait_until(lambda: r.state.polls >= polls + 3, 2, "polls going on")
        finally:
            watch.stop()
        st = r.state
        assert not watch.ever_lost and watch.trips == set()  # the run would go on
        assert st.link_ok and st.link_losses == 0 and st.failed_in_row == 0
        assert 1 <= st.poll_failures < 3
        assert st.link_error is None and r.state.to_dict()["poll_failures"] == st.poll_failures
        # nothing was interrupted: still commanded, at speed, no trip, and the wait goes on
        await r.wait_settled(hold=0.05, timeout=2)
        for dev, rpm in ((1, 1000), (2, -500)):
            assert sim.regs(dev)["FAULT"] == 0 and sim.regs(dev)["CW"] == CW_RUN
            assert sim.rpm(dev) == pytest.approx(rpm, abs=5)


async def test_failed_polls_in_a_row_declare_the_link_lost(sim, caplog):
    caplog.set_level(logging.ERROR, logger="drives")
    async with rig(sim, link_loss_polls=3, comm_loss_timeout=2.0) as r:
        await r.set_speeds(1000 * RPM, 500 * RPM)
        await r.wait_settled(hold=0.05, timeout=5)
        loop = asyncio.get_running_loop()
        watch = StateWatch(r)
        before = r.state.poll_failures  # a busy host may have timed out a read before (answered late)
        sim.endpoint.set_unresponsive(True)
        t0 = loop.time()
        await wait_until(lambda: not r.state.link_ok, 2, "link loss declared")
        took = loop.time() - t0
        await asyncio.sleep(0.02)
        watch.stop()
        assert "drive_link:fail" in watch.trips  # the sweep's interlock fails the run
        st = r.state
        # three failed polls (the row may begin with a read that timed out just before the drives
        # fell silent); or, polls slower than poll_interval + timeout on a busy machine, the
        # declaration by time (link_loss_polls x (0.05 + 0.1) s since the last good poll) after one
        # or two, counted as one, and then the poll in flight
        by_time = re.search(r"drive link lost \(since the last good poll\): .*?no answer for ([0-9.]+) s", caplog.text)
        assert st.link_losses == 1 and st.failed_in_row <= 4, st
        if by_time:  # never before the time bound ran out
            assert float(by_time[1]) >= 3 * (0.05 + 0.1) - 0.01 and st.failed_in_row >= 2, (by_time[0], st)
        else:  # not at the first failure: three request timeouts of 0.1 s
            assert st.failed_in_row >= 3 and took >= 2 * 0.1, (caplog.text[-2000:], st, took)
        assert st.poll_failures - before in (st.failed_in_row, st.failed_in_row - 1), (before, st)
        with pytest.raises(DriveLinkError, match="nothing commanded"):
            await r.set_speeds(1100 * RPM, 500 * RPM)
        sim.endpoint.set_unresponsive(False)
        st = await r.wait_settled(hold=0.05, timeout=5)  # reconnected and verified
        assert st.link_ok and st.link_losses == 1 and st.failed_in_row == 0


def test_link_loss_polls_must_be_a_positive_integer():
    for bad in (0, -1, 1.5):
        with pytest.raises(ValueError, match="link_loss_polls"):
            RigDrives("tcp://127.0.0.1:1", LIMITS, link_loss_polls=bad)


async def test_link_loss_polls_lowered_to_fit_the_watchdog(tcp_sim, caplog):
    caplog.set_level(logging.INFO, logger="drives.poll")
    # given explicitly: 3 x (0.3 + 0.05) s = 1.05 s >= 1 s watchdog -> 2 (0.7 s), warned
    async with rig(tcp_sim, timeout=0.3, comm_loss_timeout=1.0, link_loss_polls=3) as r:
        assert r.link_loss_polls == 2
    warned = [rec for rec in caplog.records if "declared lost after 2 failed poll(s)" in rec.message]
    assert warned and warned[0].levelno == logging.WARNING
    caplog.clear()
    # the default (3) is lowered quietly (the CLI's 0.5 s timeout: 1 poll)
    async with rig(tcp_sim, timeout=0.5, poll_interval=0.1, comm_loss_timeout=1.0) as r:
        assert r.link_loss_polls == 1
    assert all(rec.levelno < logging.WARNING for rec in caplog.records if "failed poll" in rec.message)
    caplog.clear()
    async with rig(tcp_sim, timeout=0.2, comm_loss_timeout=1.0, link_loss_polls=3) as r:
        assert r.link_loss_polls == 3  # 3 x 0.25 s = 0.75 s fits
    assert "failed poll(s) instead" not in caplog.text


async def test_link_loss_polls_fitted_strictly_below_the_watchdog_in_float_too(tcp_sim):
    # 0.3 s watchdog (3 x 0.1 s units read back: 0.30000000000000004) and a gap of
    # 0.05 + 0.05 s: three polls are exactly the watchdog, not below it -> 2
    async with rig(tcp_sim, timeout=0.05, poll_interval=0.05, comm_loss_timeout=0.3, link_loss_polls=5) as r:
        watchdog = r.spin.params.comm_loss_timeout
        assert r.link_loss_polls * (0.05 + 0.05) < watchdog, (r.link_loss_polls, watchdog)
        assert r.link_loss_polls == 2


async def test_link_loss_declared_in_time_while_a_stop_holds_the_link(sim):
    """The link falls silent as a stop goes out: the stop's tries (two words and two zero
    references, 1 + 2 retries each, 0.1 s apiece) hold the link for 1.2 s and the poll's failed
    reads wait behind them, so three failed polls came 1.5 s after the drop. The loss is declared
    once the link has answered nothing for link_loss_polls x (poll_interval + timeout) = 0.45 s
    since the last good poll, with the stop still trying, before the drives' watchdog would trip."""
    async with rig(sim, comm_loss_timeout=2.0) as r:  # the stop, not the watchdog, meets the silence
        await r.set_speeds(1000 * RPM, -500 * RPM)
        await r.wait_settled(hold=0.05, timeout=5)
        budget = r.link_loss_polls * (0.05 + 0.1)
        loop = asyncio.get_running_loop()
        sim.endpoint.set_unresponsive(True)
        t0 = loop.time()
        stop = asyncio.create_task(r.stop(wait=False))
        await wait_until(lambda: not r.state.link_ok, 3, "link loss declared")
        took = loop.time() - t0
        assert not stop.done(), "the stop ended before the loss was declared: nothing held the poll"
        assert budget - 0.1 <= took <= budget + 0.25, f"link loss declared {took:.2f} s after the drop"
        assert r.state.link_losses == 1
        # named as a loss by failed polls is: the last request that failed (one of the stop's words)
        said = r"^(spin|orbit) drive \(id [12]\), register (CW|REF) \([01]\): no answer for [0-9.]+ s, \d+ request"
        assert re.match(said, r.state.link_error), r.state.link_error
        with pytest.raises(DriveTimeoutError, match="no answer within"):
            await stop
        sim.endpoint.set_unresponsive(False)
        await wait_until(lambda: r.state.link_ok, 3, "the link back")
