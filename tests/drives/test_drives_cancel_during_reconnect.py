"""A cancel that arrives while the drives' link reconnects is never lost.

The poll reconnects the link when it has dropped (a USB-serial adapter pulled and put back, a
TCP connection reset). If the run leaves its `async with RigDrives` in the very loop step in
which that reconnect ends, the exit's cancel of the poll must still end the poll, and the exit
must go on to stop both drives. Python 3.11's asyncio.wait_for returned the connect's outcome
and dropped the cancel: the poll went on feeding the drives' watchdog, the exit waited for it
forever and no stop word was sent. The alignment of the connect's end and the exit in one
loop step is the one thing the real parts cannot be made to produce on demand; everything
else is the simulator's drives behind its real Modbus server."""

from __future__ import annotations

import asyncio

import pytest
from support.drives_testkit import CW_RAMP_STOP, RPM, SimDrives, open_rig

from drives import rig as rig_module
from drives.limits import DriveLimits
from drives.link import ModbusLink

pytestmark = pytest.mark.timeout(60)

LIMITS = DriveLimits(2400 * RPM, 2400 * RPM)


class RunFailed(Exception):
    """Any failure of the run inside its `async with RigDrives`."""


def _reconnect_that_wakes(link: ModbusLink, woke: asyncio.Event, fails: bool) -> None:
    """The link's next connect ends (ok, or the adapter still gone) and wakes the run in the
    same loop step; the connects after it are the link's own."""
    new_client = link._new_client

    def client():
        link._new_client = new_client
        c = new_client()
        connect = c.connect

        async def connect_and_wake():
            if fails:
                woke.set()
                raise OSError("the serial adapter is gone")
            ok = await connect()
            woke.set()
            return ok

        c.connect = connect_and_wake
        return c

    link._new_client = client


@pytest.mark.parametrize("fails", [False, True], ids=["reconnected", "still-gone"])
async def test_leaving_the_rig_as_the_poll_reconnects_stops_both_drives(tcp_sim: SimDrives, fails):
    rig = open_rig(tcp_sim, LIMITS)
    woke = asyncio.Event()

    async def run() -> None:
        async with rig:
            await rig.set_speeds(1200 * RPM, 600 * RPM)
            await rig.wait_settled(hold=0.1, timeout=20)
            _reconnect_that_wakes(rig.link, woke, fails)
            rig.link._drop()  # the link dropped: the next poll reconnects
            await woke.wait()
            raise RunFailed("leave the block in the loop step in which the reconnect ends")

    task = asyncio.create_task(run())
    done, _ = await asyncio.wait({task}, timeout=6.0)
    polls = [t for t in asyncio.all_tasks() if t.get_name().startswith("drives-poll") and not t.done()]
    for t in polls:
        t.cancel()
    if not done:
        task.cancel()
    await asyncio.gather(task, *polls, return_exceptions=True)
    assert done, "the exit waited for the poll forever: the cancel was dropped, no stop sent"
    assert isinstance(task.exception(), RunFailed)
    assert not polls, "the poll outlived the rig (it would feed the drives' watchdog)"
    assert tcp_sim.regs(1)["CW"] == CW_RAMP_STOP and tcp_sim.regs(2)["CW"] == CW_RAMP_STOP
    await tcp_sim.wait_stopped(timeout=10.0)


async def test_a_poll_that_outlives_its_cancel_does_not_hold_back_the_stop(tcp_sim: SimDrives):
    """Whatever keeps the poll from ending on its cancel, the exit stops both drives after at
    most POLL_END_S (it does not wait on the poll first) and cancels the poll again."""
    rig = open_rig(tcp_sim, LIMITS)
    run_poll = rig._poll.run

    async def poll_that_swallows_a_cancel():  # the fault itself: no real part drops a cancel on demand
        try:
            await run_poll()
        except asyncio.CancelledError:
            await run_poll()

    rig._poll.run = poll_that_swallows_a_cancel
    loop = asyncio.get_running_loop()
    with pytest.raises(RunFailed):
        async with rig:
            await rig.set_speeds(1200 * RPM, 600 * RPM)
            await rig.wait_settled(hold=0.1, timeout=20)
            t0 = loop.time()
            raise RunFailed("leave the block")
    assert loop.time() - t0 < rig_module.POLL_END_S + 2.0
    assert tcp_sim.regs(1)["CW"] == CW_RAMP_STOP and tcp_sim.regs(2)["CW"] == CW_RAMP_STOP
    await asyncio.sleep(0.1)
    assert not [t for t in asyncio.all_tasks() if t.get_name().startswith("drives-poll") and not t.done()]
    await tcp_sim.wait_stopped(timeout=10.0)


async def test_a_cancel_of_a_released_rig_still_stops_both_drives(tcp_sim: SimDrives):
    """`release()` leaves the drives at their setpoint only on a clean exit: a Ctrl-C of `drives
    run` that lands while the exit waits for the poll stops them and stays a cancellation."""
    rig = open_rig(tcp_sim, LIMITS, comm_loss_timeout=0.0)  # no watchdog: only the stop ends the turning

    async def command() -> str:
        async with rig:
            await rig.set_speeds(1200 * RPM, 600 * RPM)
            await rig.wait_settled(hold=0.1, timeout=20)
            rig.release()
            asyncio.get_running_loop().call_soon(me.cancel)  # the signal handler's task.cancel()
        return "left at the setpoint"

    me = asyncio.create_task(command())
    await asyncio.gather(me, return_exceptions=True)
    assert me.cancelled()
    assert tcp_sim.regs(1)["CW"] == CW_RAMP_STOP and tcp_sim.regs(2)["CW"] == CW_RAMP_STOP
    await tcp_sim.wait_stopped(timeout=10.0)
