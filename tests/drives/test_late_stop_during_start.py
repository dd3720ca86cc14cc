"""A stop's word the link gave up on reaches the spin drive during the next start's own
confirmation: after the run word was taken, before a read showed the drive running. Before the
mend the start waited out its state timeout (2 s) and ended with 'operation enabled (RDY_REF) not
reached', the late word unnamed. Now the first read showing the drive not running with our own
stop word read back ends the start at once, naming it as the poll does (late.stopped_late), and
both drives are stopped. Real parts: the simulator's Modbus server behind a real TCP proxy
(support.modbus_proxy) that holds the spin drive's first ramp stop word (CW 0x047E) past the
request timeout and delivers it as soon as it has forwarded the spin drive's next run word."""

from __future__ import annotations

import time

import pytest
from support.drives_testkit import CW_RAMP_STOP, CW_RUN, RPM
from support.modbus_proxy import HoldingProxy, first_write, write_of

from drives import registers as R
from drives.errors import DriveOffCommand
from drives.limits import DriveLimits
from drives.rig import RigDrives

pytestmark = pytest.mark.timeout(30)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM, min_ratio=None, max_ratio=1.0)
TIMEOUT = 0.5  # s a request: the stop word is given up after it, and may arrive for 1.0 s more
STATE_TIMEOUT = 2.0  # s a start waits for a state (the old code's wait before it gave up)


async def test_a_stop_word_given_up_landing_in_the_start_is_named_and_ends_it_at_once(tcp_sim):
    """Before the mend: DriveTimeoutError 'operation enabled (RDY_REF) not reached within 2 s'."""
    proxy = HoldingProxy(tcp_sim.endpoint.port, first_write(1, R.CW, CW_RAMP_STOP))
    url = await proxy.start()
    try:
        async with RigDrives(
            url, LIMITS, poll_interval=0.05, timeout=TIMEOUT, comm_loss_timeout=2.0, state_timeout=STATE_TIMEOUT
        ) as r:
            await r.set_speeds(600 * RPM, 300 * RPM)
            await r.wait_settled(hold=0.05, timeout=5)
            await r.stop(wait=True, timeout=5)  # the spin word given up after 0.5 s, its retry taken
            assert proxy.held and tcp_sim.regs(1)["ACT"] == 0
            words_before = {dev: len(tcp_sim.models[dev].control_words) for dev in (1, 2)}
            proxy.release_after(0.0, lambda frame: write_of(frame) == (1, R.CW, CW_RUN))
            t0 = time.monotonic()
            with pytest.raises(DriveOffCommand) as info:
                await r.set_speeds(600 * RPM, 300 * RPM)  # the stale word lands after its run word
            took = time.monotonic() - t0
            assert proxy.released.is_set()
            await tcp_sim.wait_stopped(timeout=5)
    finally:
        await proxy.aclose()
    words = str(info.value)
    assert words.startswith(
        "spin drive (id 1), register SW (3): operation enabled (RDY_REF) not reached (status word 0x"
    ), words
    assert ": most likely our own stop word given up unanswered at " in words, words
    assert "before this read: CW (0) = 0x047E) reached it late, after the start, and the drive stopped on" in words
    assert info.value.drive == 1 and info.value.register == R.SW
    assert took < STATE_TIMEOUT, took  # ended at the read, not at the state timeout
    spin = [cw for _, cw in tcp_sim.models[1].control_words][words_before[1] :]
    assert spin[spin.index(CW_RUN) + 1] == CW_RAMP_STOP and spin.count(CW_RUN) == 1, [hex(cw) for cw in spin]
    orbit = [cw for _, cw in tcp_sim.models[2].control_words][words_before[2] :]
    assert CW_RUN not in orbit and orbit[-1] == CW_RAMP_STOP, [hex(cw) for cw in orbit]  # never started
    assert tcp_sim.regs(1)["REF"] == 0 and tcp_sim.regs(2)["REF"] == 0  # both stopped
