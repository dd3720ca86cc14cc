"""A start's words the link gave up on (no answer in time: a slow path held them) reach the drive
after the stop that followed, which went out on a new connection: the drive runs again. Real
parts: the simulator's Modbus server behind a real TCP proxy (support.modbus_proxy) that holds the
spin drive's first REF write and every try of its run word (CW 0x047F), and delivers them 0.1 s
after it forwarded the stop's word. Before the mend the stop was reported done (the run's closing
stop confirmed at standstill, the rig closed) and the spin drive then ran at the stale start's
600 rpm with nobody polling it (COMM_LOSS_TIMEOUT 0: its watchdog off). Now the stop is not done
until the drives have been read at rest by reads sent after every write the link gave up on can
still arrive (drives/late.py); the one found running again gets the stop word again, said."""

from __future__ import annotations

import asyncio
import logging
import time

import pytest
from support.drives_testkit import CW_RAMP_STOP, CW_RUN, CW_EMERGENCY, RPM
from support.modbus_proxy import HoldingProxy, write_of

from drives.errors import DriveTimeoutError
from drives.late import LATE_TIMEOUTS
from drives.limits import DriveLimits
from drives.rig import RigDrives

pytestmark = pytest.mark.timeout(30)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM, min_ratio=None, max_ratio=1.0)
TIMEOUT = 0.25  # s a request (late window 0.5 s); the proxy delivers the held words 0.1 s after the stop's word
RDY_REF = 0x0004
REF_600_RPM = 4000  # 600 rpm at SPEED_SCALE 3000 rpm = 20000


async def _proxy(tcp_sim) -> tuple[HoldingProxy, str]:
    first_ref = [True]

    def hold(frame: bytes) -> bool:
        write = write_of(frame)
        if write is None or write[0] != 1:
            return False
        if write[1:] == (1, REF_600_RPM) and first_ref[0]:  # REF: its first try (the retry gets through)
            first_ref[0] = False
            return True
        return write[1:] == (0, CW_RUN)  # the run word: every try

    proxy = HoldingProxy(tcp_sim.endpoint.port, hold)
    stop_words = {(1, 0, CW_RAMP_STOP), (1, 0, CW_EMERGENCY)}
    proxy.release_after(0.1, lambda f: write_of(f) in stop_words)  # 0.1 s after the stop's word to it
    return proxy, await proxy.start()


def _rig(url: str) -> RigDrives:
    return RigDrives(url, LIMITS, poll_interval=0.05, timeout=TIMEOUT, comm_loss_timeout=0.0)


async def _spin_after_release(proxy: HoldingProxy, tcp_sim) -> dict[str, int]:
    await asyncio.wait_for(proxy.released.wait(), 5)
    await asyncio.sleep(0.1)  # the stale words are served; a drive started by them ramps up
    return tcp_sim.regs(1)


def _said_again(caplog) -> list[str]:
    """The warnings that a write given up reached the spin drive late: they name the drive, the
    register read (CW: operation enabled; REF: nonzero, whichever the stale words set first) and
    the writes given up."""
    said = [
        r.getMessage() for r in caplog.records if r.levelno == logging.WARNING and "reached it late" in r.getMessage()
    ]
    assert all(m.startswith("spin drive (id 1): register ") for m in said), said
    assert all("REF (1) = 0x0FA0, CW (0) = 0x047F" in m for m in said), said
    return said


@pytest.mark.parametrize("emergency", [False, True])
async def test_the_stop_is_not_confirmed_until_a_stale_start_can_no_longer_arrive(tcp_sim, caplog, emergency):
    """Before the mend: after the ramp stop the spin drive ran at 600 rpm; after the emergency stop
    (switch-on inhibited: the drive profile's run word alone does not start it) it held the run
    word and a 600 rpm REF, the stop's zero reference undone."""
    proxy, url = await _proxy(tcp_sim)
    caplog.set_level(logging.WARNING)
    try:
        async with _rig(url) as r:
            with pytest.raises(DriveTimeoutError):
                await r.set_speeds(600 * RPM, 300 * RPM)
            assert proxy.held  # the run word, held
            t0 = time.monotonic()
            await r.stop(emergency=emergency, wait=True, timeout=5)
            took, released_in_the_stop = time.monotonic() - t0, proxy.released.is_set()
        spin = await _spin_after_release(proxy, tcp_sim)
    finally:
        await proxy.aclose()
    assert not spin["SW"] & RDY_REF and spin["CW"] in (CW_RAMP_STOP, CW_EMERGENCY), spin
    assert spin["REF"] == 0, spin
    assert released_in_the_stop  # the stale words came during the stop's wait
    await tcp_sim.wait_for(lambda: tcp_sim.regs(1)["ACT"] == 0, 3, "spin at rest")
    assert _said_again(caplog)
    # the wait lasts the late window (LATE_TIMEOUTS request timeouts past the last give-up, which
    # came just before set_speeds' own stop) and a read
    assert LATE_TIMEOUTS * TIMEOUT * 0.6 < took < 3.0, took
    assert proxy.resets >= 3  # each connection given up was reset (RST), not closed


async def test_the_exit_after_a_failed_start_watches_until_a_stale_start_can_no_longer_arrive(tcp_sim, caplog):
    proxy, url = await _proxy(tcp_sim)
    caplog.set_level(logging.WARNING)
    try:
        with pytest.raises(DriveTimeoutError):
            async with _rig(url) as r:
                await r.set_speeds(600 * RPM, 300 * RPM)  # raises: the exit stops both
        released_in_the_exit = proxy.released.is_set()
        spin = await _spin_after_release(proxy, tcp_sim)
    finally:
        await proxy.aclose()
    assert not spin["SW"] & RDY_REF and spin["REF"] == 0, spin
    assert released_in_the_exit
    assert _said_again(caplog)
