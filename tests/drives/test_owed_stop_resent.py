"""A stop that does not reach both drives is owed: once the drives answer again (after a declared
link loss and its reconnect, or with the link never declared lost), a drive found running while
no speed is commanded gets the stop again (the emergency stop if that is what was owed), and the
failure that names it is raised to the owner. On the simulator's drives over real Modbus (TCP,
RTU on a pty); the outage is the simulator's own (no answers). Their comm-loss watchdog is set
to 5 s so that it never stops them during these outages: whatever stops them is a command."""

from __future__ import annotations

import asyncio

import pytest
from support.drives_testkit import CW_EMERGENCY, CW_RAMP_STOP, CW_RUN, RPM, open_rig, wait_until

from drives.errors import DriveError, DriveLinkError
from drives.limits import DriveLimits

pytestmark = pytest.mark.timeout(60)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM)
WATCHDOG_S = 5.0


async def raised_by_check(r, timeout: float) -> DriveError:
    """What `r.check()` raises, once it does (the poll records a failure once the stop it sends
    for it has gone out, zero references included)."""
    loop = asyncio.get_running_loop()
    t_end = loop.time() + timeout
    while True:
        try:
            r.check()
        except DriveError as err:
            return err
        assert loop.time() < t_end, f"no failure raised within {timeout} s"
        await asyncio.sleep(0.01)


async def _stop_lost(r, sim, emergency: bool) -> None:
    """The drives at speed, then a stop asked while they do not answer: it raises (not delivered)."""
    await r.set_speeds(1000 * RPM, -500 * RPM)
    await r.wait_settled(hold=0.05, timeout=5)
    sim.endpoint.set_unresponsive(True)
    with pytest.raises(DriveError, match="no answer"):
        await r.stop(emergency=emergency, wait=False)
    for dev in (1, 2):  # still running at speed: nothing reached them
        assert sim.regs(dev)["CW"] == CW_RUN and sim.regs(dev)["FAULT"] == 0


@pytest.mark.parametrize("emergency", [False, True], ids=["ramp", "emergency"])
async def test_owed_stop_is_sent_again_once_the_link_is_back(sim, emergency):
    word = CW_EMERGENCY if emergency else CW_RAMP_STOP
    async with open_rig(sim, LIMITS, comm_loss_timeout=WATCHDOG_S) as r:
        await _stop_lost(r, sim, emergency)
        await wait_until(lambda: not r.state.link_ok, 3, "the link declared lost")
        sim.endpoint.set_unresponsive(False)
        await sim.wait_for(lambda: sim.regs(1)["CW"] == sim.regs(2)["CW"] == word, 3, "the owed stop at both drives")
        await sim.wait_stopped(timeout=3)
        err = await raised_by_check(r, 3)
        assert isinstance(err, DriveLinkError) and "link was down" in str(err), err
        kind = "emergency stop (OFF3)" if emergency else "ramp stop (OFF1)"
        assert f"while no speed is commanded: the {kind} it missed (not delivered) is sent again" in str(err)
        assert r.state.link_ok and r.state.link_losses == 1
        assert r._poll.owed is None  # delivered to both now: nothing owed
        for dev in (1, 2):  # stopped by the command, not by their watchdog (fault 7510)
            assert sim.regs(dev)["FAULT"] == 0 and sim.regs(dev)["REF"] == 0


async def test_owed_stop_is_sent_again_when_the_link_comes_back_before_a_loss_is_declared(sim):
    """The stop's tries hold the silent link 1.2 s (TCP) to 2 s (RTU, which settles after each
    missed answer); with 20 polls' time (3 s) to a declared loss it answers again before that."""
    async with open_rig(sim, LIMITS, comm_loss_timeout=WATCHDOG_S, link_loss_polls=20) as r:
        await _stop_lost(r, sim, emergency=False)
        sim.endpoint.set_unresponsive(False)  # at once: the next polls are answered
        await sim.wait_for(lambda: sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RAMP_STOP, 3, "the owed stop")
        await sim.wait_stopped(timeout=3)
        err = await raised_by_check(r, 3)
        assert isinstance(err, DriveLinkError), err
        assert "while no speed is commanded: the ramp stop (OFF1) it missed (not delivered) is sent again" in str(err)
        assert r.state.link_losses == 0  # no reconnect: the polls saw the drives running
        for dev in (1, 2):
            assert sim.regs(dev)["FAULT"] == 0
