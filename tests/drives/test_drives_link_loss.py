"""Heartbeat, communication loss and link loss against the simulator's drives.

The drives' comm-loss watchdog runs in wall time (COMM_LOSS_TIMEOUT 0.5 s here).
"""

from __future__ import annotations

import asyncio
import signal
import sys

import pytest
from drives_testkit import CW_RAMP_STOP, CW_RUN, ROOT, RPM, open_rig, subprocess_env

from drives.errors import DriveFaultError, DriveLinkError
from drives.rig import DriveLimits, RigDrives
from sim.modbus_server import serve_modbus_tcp

pytestmark = pytest.mark.timeout(30)  # a hang fails fast, with a traceback

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM)


def rig(sim, **kw) -> RigDrives:
    return open_rig(sim, LIMITS, **kw)


async def wait_until(cond, timeout: float, what: str) -> None:
    loop = asyncio.get_running_loop()
    t_end = loop.time() + timeout
    while not cond():
        assert loop.time() < t_end, f"{what} not within {timeout} s"
        await asyncio.sleep(0.01)


async def test_poll_keeps_the_watchdog_fed_while_the_caller_waits(sim):
    async with rig(sim) as r:
        await r.set_speeds(1000 * RPM, -500 * RPM)
        await r.wait_settled(hold=0.05, timeout=5)
        polls = r.state.polls
        await asyncio.sleep(1.2)  # more than twice COMM_LOSS_TIMEOUT doing something else
        # 24 expected at 0.05 s; a request lost on a loaded machine costs 6 (0.3 s timeout)
        assert r.state.polls - polls >= 10
        for dev in (1, 2):
            assert sim.regs(dev)["FAULT"] == 0 and sim.regs(dev)["CW"] == CW_RUN
        assert r.state.at_setpoint and r.state.link_ok


CLIENT = """
import asyncio, sys
from drives.rig import DriveLimits, RigDrives

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
    proc = await asyncio.create_subprocess_exec(
        sys.executable, "-c", CLIENT, sim.url,
        cwd=ROOT, env=subprocess_env(), stdout=asyncio.subprocess.PIPE,
    )
    try:
        line = await asyncio.wait_for(proc.stdout.readline(), 15)
        assert line == b"settled\n"
        await asyncio.sleep(0.3)
        assert sim.regs(1)["FAULT"] == 0 and sim.rpm(1) == pytest.approx(150 / RPM, abs=5)
    finally:
        proc.send_signal(signal.SIGKILL)  # no cleanup code runs in the client
        await proc.wait()
    took = await sim.wait_for(
        lambda: sim.regs(1)["FAULT"] == 7510 and sim.regs(2)["FAULT"] == 7510, 3, "fault 7510"
    )
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
        assert r.link.connects >= 2
        for dev, rpm in ((1, 1000), (2, 500)):
            assert sim.regs(dev)["FAULT"] == 0 and sim.rpm(dev) == pytest.approx(rpm, abs=5)


async def test_link_loss_longer_than_the_watchdog(sim):
    async with rig(sim) as r:
        await r.set_speeds(1500 * RPM, -1000 * RPM)
        await r.wait_settled(hold=0.05, timeout=5)
        sim.endpoint.set_unresponsive(True)
        # the drives' own watchdog stops them
        await sim.wait_for(
            lambda: sim.regs(1)["FAULT"] == 7510 and sim.regs(2)["FAULT"] == 7510, 3, "7510"
        )
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
