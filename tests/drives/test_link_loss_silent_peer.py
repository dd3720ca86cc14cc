"""A drives' server that falls silent without closing its connection (frozen: SIGSTOP; a peer gone
with no FIN) is told by nothing but the missing answers: pymodbus' `callback_disconnected`, which
`drives.connection.watch_loss` relies on for a connection reset or closed, never comes. The poll's
timeouts declare the link lost all the same, within link_loss_polls x (poll interval + request
timeout) s; the sweep's interlock fails the run on it and a `run --hold` ends on it
(`require_link`); once the server answers again, its drives' own comm-loss watchdog has tripped
(7510) and the verification after the reconnect stops both and raises it.

The simulator's drives in a subprocess of their own (so that it can be frozen), served over a real
Modbus TCP socket; the client is the rig's RigDrives.
"""

from __future__ import annotations

import asyncio
import signal
import sys

import pytest
from support.cli_helpers import reaped_async, started_async
from support.drives_testkit import CW_RAMP_STOP, RPM, wait_until

from drives.errors import DriveFaultError, DriveLinkError
from drives.limits import DriveLimits
from drives.link import ModbusLink
from drives.rig import RigDrives
from orbitrig.config import Interlocks
from orbitrig.run import interlocks

pytestmark = pytest.mark.timeout(30)

SERVER = """
import asyncio, time
from sim.drive_model import DriveModel
from sim.modbus_server import serve_modbus_tcp

async def main():
    t0 = time.monotonic()
    clock = lambda: (time.monotonic() - t0) * 25.0  # ramps sped up, the watchdog in wall time
    models = {1: DriveModel(1, clock=clock, bidirectional=False), 2: DriveModel(2, clock=clock, bidirectional=True)}
    endpoint = await serve_modbus_tcp(models)
    print(endpoint.url, flush=True)
    await asyncio.Event().wait()

asyncio.run(main())
"""

POLL, TIMEOUT, WATCHDOG = 0.05, 0.1, 0.5  # s: 3 failed polls x 0.15 s declare the loss before 0.5 s


async def _registers(url: str) -> list[list[int]]:
    """CW .. FAULT of both drives, read by a client of its own (not drives/' poll)."""
    async with ModbusLink(url, timeout=1.0) as link:
        return [await link.read(dev, 0, 7) for dev in (1, 2)]


async def test_a_frozen_server_is_a_lost_link_by_the_polls_timeouts_and_the_drives_end_stopped():
    server = await started_async([sys.executable, "-c", SERVER], stderr=None)  # SIGKILL ends it frozen too
    async with reaped_async(server):
        url = (await asyncio.wait_for(server.stdout.readline(), 15)).decode().strip()
        limits = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM)
        async with RigDrives(url, limits, poll_interval=POLL, timeout=TIMEOUT, comm_loss_timeout=WATCHDOG) as r:
            await r.set_speeds(1000 * RPM, -500 * RPM)
            await r.wait_settled(hold=0.05, timeout=5)
            lost_told = r.link._lost  # pymodbus' disconnect callback of this connection (watch_loss)
            loop = asyncio.get_running_loop()
            server.send_signal(signal.SIGSTOP)
            t0 = loop.time()
            await wait_until(lambda: not r.state.link_ok, 3, "link loss declared")
            took = loop.time() - t0
            assert lost_told is not None and not lost_told.done()  # no disconnect was ever reported
            assert "no answer within 0.1 s" in r.state.link_error, r.state.link_error
            assert 2 * TIMEOUT <= took < 2.0, took  # three polls' timeouts (a busy host: a little later)
            trips = interlocks.check(None, r.state, Interlocks(), pressure_armed=False)
            assert [f"{t.kind}:{t.action}" for t in trips] == ["drive_link:fail"], trips  # the sweep's interlock
            with pytest.raises(DriveLinkError, match="link"):
                r.check().require_link()  # `drives run --hold` ends on it
            await asyncio.sleep(WATCHDOG)  # frozen longer than the drives' watchdog
            server.send_signal(signal.SIGCONT)
            with pytest.raises(DriveFaultError, match="while the link was down") as raised:
                await r.wait_settled(hold=0.05, timeout=5)
            assert raised.value.fault_code == 7510 and r.state.link_losses == 1
        regs = await _registers(url)
        assert [w[0] for w in regs] == [CW_RAMP_STOP, CW_RAMP_STOP], regs  # verified, then stopped
        assert all(w[6] == 7510 for w in regs), regs  # their own watchdog ramped them down meanwhile
