"""A drive held at its keypad (local control) whose refusal is a 'busy' answer (exception 06, which
may pass): the rig's stop sends its word again every 0.1 s until its wait ends (drives/stop_again.py),
and each refusal was an ERROR of its own. The sends again are said at the pace of the poll's
(drives/local_hold.py, their one owner): the refusal once, the hold once when it starts, then
DEBUG lines, and once when the drive takes the stop; the word still goes again as often.

Real parts: the simulator's drives over Modbus TCP, through a real proxy that makes the keypad's
refusal (the simulator answers 03, illegal data value) the busy answer (06) some drives give."""

from __future__ import annotations

import asyncio
import logging

import pytest
from support.drives_testkit import RPM, drive_lines
from support.modbus_proxy import HoldingProxy, exception_code

from drives.limits import DriveLimits
from drives.rig import RigDrives

pytestmark = pytest.mark.timeout(60)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM)
REFUSED = "orbit drive (id 2), register CW (0): did not take the ramp stop (OFF1, 0x047E): in local control"


async def test_the_stop_sent_again_to_a_drive_held_at_its_keypad_is_said_at_the_holds_pace(tcp_sim):
    sim = tcp_sim
    proxy = HoldingProxy(sim.endpoint.port, lambda frame: False, lambda frame: exception_code(frame, 0x03, 0x06))
    url = await proxy.start()
    try:
        with drive_lines() as lines:
            async with RigDrives(url, LIMITS, poll_interval=0.05, timeout=0.1, comm_loss_timeout=1.0) as rig:
                await rig.set_speeds(100.0, -50.0)
                sim.models[2].local_control(-300.0)
                with pytest.raises(Exception, match="in local control"):
                    await rig.stop(timeout=1.5)
                again = rig.stop_again
                sim.models[2].hand_back()
                await sim.wait_stopped(5.0)
    finally:
        await proxy.aclose()
    sent = int(again.split("sent again ")[1].split(" time")[0])
    assert sent >= 3, again  # the word still went again every 0.1 s (until its watchdog is starved, 0.6 s)
    # the stop's own refusal and its first send again's, which starts the hold: not one per send
    loud = lines.said(logging.ERROR, "stop command not delivered", REFUSED)
    assert len(loud) <= 2, (sent, loud)
    assert len(lines.said(logging.WARNING, "orbit drive (id 2): request FC06 refused", "trying again")) <= 4
    started = lines.said(logging.WARNING, "orbit drive (id 2) in local control (status word REMOTE = 0)")
    assert len(started) == 1, lines.lines
    assert len(lines.said(logging.WARNING, "orbit drive (id 2) took the ramp stop (OFF1) sent again")) == 1


def _busy_cw_answer(busy: dict[str, bool]):
    """Answers as the drives give them: the keypad's refusal 06 (the simulator's 03); while `busy["on"]`,
    the orbit drive's answer to a control word write is 06 busy as well, in network control (REMOTE = 1)."""

    def answer(frame: bytes) -> bytes:
        if busy["on"] and len(frame) == 12 and frame[6] == 2 and frame[7] == 0x06 and frame[8:10] == b"\x00\x00":
            return frame[:4] + (3).to_bytes(2, "big") + frame[6:7] + bytes([0x86, 0x06])
        return exception_code(frame, 0x03, 0x06)

    return answer


async def test_a_drive_once_held_that_refuses_the_stop_in_network_control_is_said_at_error(tcp_sim):
    """A drive known held whose keypad gives control back, and that then refuses the stop for another
    reason (busy, REMOTE = 1): a stop not taken by a drive not in local control is an ERROR, never
    a DEBUG line of the hold's pace."""
    sim, busy = tcp_sim, {"on": False}
    proxy = HoldingProxy(sim.endpoint.port, lambda frame: False, _busy_cw_answer(busy))
    url = await proxy.start()
    try:
        with drive_lines() as lines:
            async with RigDrives(url, LIMITS, poll_interval=0.05, timeout=0.1, comm_loss_timeout=1.0) as rig:
                await rig.set_speeds(100.0, -50.0)
                sim.models[2].local_control(-300.0)
                stop = asyncio.create_task(rig.stop(timeout=2.0))
                for _ in range(100):  # the hold is known (its WARNING), then the keypad gives control back
                    if lines.said(logging.WARNING, "orbit drive (id 2) in local control (status word REMOTE = 0)"):
                        break
                    await asyncio.sleep(0.02)
                before = len(lines.lines)
                busy["on"] = True
                sim.models[2].hand_back()
                with pytest.raises(Exception, match="exception"):
                    await stop
                busy["on"] = False
                await sim.wait_stopped(5.0)
    finally:
        await proxy.aclose()
    after = [(lv, m) for lv, m in lines.lines[before:] if "stop command not delivered: orbit drive (id 2)" in m]
    assert after, lines.lines[before:]
    not_local = [(lv, m) for lv, m in after if "local control" not in m]
    assert not_local, after  # the drive read REMOTE = 1: its refusal is not the keypad's
    assert all(lv == logging.ERROR for lv, _ in not_local), not_local
