"""A drive held at its keypad (local control) whose refusal is a 'busy' answer (exception 06, which
may pass): the rig's stop sends its word again every 0.1 s until its wait ends (drives/stop_again.py),
and each refusal was an ERROR of its own. The sends again are said at the pace of the poll's
(drives/local_hold.py, their one owner): the refusal once, the hold once when it starts, then
DEBUG lines, and once when the drive takes the stop; the word still goes again as often.

Real parts: the simulator's drives over Modbus TCP, through a real proxy that makes the keypad's
refusal (the simulator answers 03, illegal data value) the busy answer (06) some drives give."""

from __future__ import annotations

import logging

import pytest
from support.drives_testkit import RPM
from support.modbus_proxy import HoldingProxy, exception_code

from drives.limits import DriveLimits
from drives.rig import RigDrives

pytestmark = pytest.mark.timeout(60)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM)
REFUSED = "orbit drive (id 2), register CW (0): did not take the ramp stop (OFF1, 0x047E): in local control"


class _Lines(logging.Handler):
    """Every record of the drives' loggers, at DEBUG too: (level, message)."""

    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.lines: list[tuple[int, str]] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.lines.append((record.levelno, record.getMessage()))

    def said(self, level: int, *words: str) -> list[str]:
        return [m for lv, m in self.lines if lv == level and all(w in m for w in words)]


async def test_the_stop_sent_again_to_a_drive_held_at_its_keypad_is_said_at_the_holds_pace(tcp_sim):
    sim = tcp_sim
    proxy = HoldingProxy(sim.endpoint.port, lambda frame: False, lambda frame: exception_code(frame, 0x03, 0x06))
    url = await proxy.start()
    lines, drives_log = _Lines(), logging.getLogger("drives")
    drives_log.addHandler(lines)
    old_level, drives_log.level = drives_log.level, logging.DEBUG
    try:
        async with RigDrives(url, LIMITS, poll_interval=0.05, timeout=0.1, comm_loss_timeout=1.0) as rig:
            await rig.set_speeds(100.0, -50.0)
            sim.models[2].local_control(-300.0)
            with pytest.raises(Exception, match="in local control"):
                await rig.stop(timeout=1.5)
            again = rig.stop_again
            sim.models[2].hand_back()
            await sim.wait_stopped(5.0)
    finally:
        drives_log.removeHandler(lines)
        drives_log.setLevel(old_level)
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
