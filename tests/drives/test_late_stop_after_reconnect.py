"""A stop's word the link gave up on reaches the spin drive while the link is down, after the
drives were started again: the verification after the reconnect finds the drive off its command.
Before the mend it blamed another client or the keypad (findings.reconnect_problem called
off_command without the late stop's cause); now it names our own stop word, as the poll does.
Real parts: the simulator's Modbus server behind a real TCP proxy (support.modbus_proxy) that
holds the spin drive's first ramp stop word (CW 0x047E), then resets every connection (`cut`:
the link is declared lost) and delivers the held word as the path comes back."""

from __future__ import annotations

import time

import pytest
from support.drives_testkit import CW_RAMP_STOP, CW_RUN, RPM, wait_until
from support.modbus_proxy import HoldingProxy, first_write

from drives import registers as R
from drives.errors import DriveLinkError
from drives.limits import DriveLimits
from drives.rig import RigDrives

pytestmark = pytest.mark.timeout(30)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM, min_ratio=None, max_ratio=1.0)
TIMEOUT = 1.0  # s a request: the stop word may arrive for 2.0 s after it was given up


async def test_a_stop_word_given_up_found_after_a_reconnect_is_named_as_the_cause(tcp_sim):
    """Before the mend: 'link was down ... found it is no longer running ...: stopped or changed by
    another client, or at the drive'."""
    proxy = HoldingProxy(tcp_sim.endpoint.port, first_write(1, R.CW, CW_RAMP_STOP))
    url = await proxy.start()
    try:
        async with RigDrives(
            url, LIMITS, poll_interval=0.05, timeout=TIMEOUT, comm_loss_timeout=3.0, link_loss_polls=2
        ) as r:
            await r.set_speeds(600 * RPM, 300 * RPM)
            await r.wait_settled(hold=0.05, timeout=5)
            await r.stop(wait=False)  # the spin word given up after 1.0 s, its retry taken
            given_up = r.link.late.open([1])[0].at
            await r.set_speeds(600 * RPM, 300 * RPM)  # started again: running, confirmed
            words_before = len(tcp_sim.models[1].control_words)
            proxy.cut()  # the path broken: two polls fail at once, the link is declared lost
            await wait_until(lambda: not r.state.link_ok, TIMEOUT, "the link declared lost")
            proxy.restore()
            await proxy.release()  # the stale ramp stop word reaches the spin drive, then the polls
            with pytest.raises(DriveLinkError) as info:
                await r.wait_settled(hold=5.0, timeout=5)
            verified = time.monotonic()
            await tcp_sim.wait_stopped(timeout=5)
    finally:
        await proxy.aclose()
    words = str(info.value)
    assert words.startswith("spin drive (id 1), register SW (3): link was down "), words
    assert "found it is no longer running (ready to switch on" in words, words
    assert "most likely our own stop word given up unanswered at " in words, words
    assert "CW (0) = 0x047E) reached it late, after the start" in words, words
    assert "another client, or at the drive" not in words, words
    assert verified - given_up < 2 * TIMEOUT + 1.0, verified - given_up  # read within the window
    after = [cw for _, cw in tcp_sim.models[1].control_words][words_before:]
    assert after[0] == CW_RAMP_STOP and CW_RUN not in after, [hex(cw) for cw in after]  # not started again
    assert tcp_sim.regs(1)["REF"] == 0 and tcp_sim.regs(2)["REF"] == 0  # both stopped
