"""A stop's word the link gave up on (no answer in time: a slow path held it) reaches the drive
after the next start, which went out on a new connection: the drive the operator just started
stops. Safe-side, but before the mend unexplained: a stop's words were not recorded as given up,
so the poll's finding blamed another client or the keypad. Real parts: the simulator's Modbus
server behind a real TCP proxy (support.modbus_proxy) that holds the spin drive's first ramp stop
word (CW 0x047E) past the request timeout and delivers it once the next start is confirmed. Now
the finding names our own stop word, the register it wrote and when it was given up; both drives
are stopped and the failure is raised (the run fails that point), the drive is not started again."""

from __future__ import annotations

import datetime as dt
import re
import time

import pytest
from support.drives_testkit import CW_RAMP_STOP, CW_RUN, RPM
from support.modbus_proxy import HoldingProxy, first_write

from drives import registers as R
from drives.drive import DriveStatus
from drives.errors import DriveOffCommand
from drives.late import LateWrites, stopped_late
from drives.limits import DriveLimits
from drives.rig import RigDrives

pytestmark = pytest.mark.timeout(30)

LIMITS = DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM, min_ratio=None, max_ratio=1.0)
TIMEOUT = 0.5  # s a request: the stop word is given up after it, and may arrive for 1.0 s more
LATE_STOP = (
    r"spin drive \(id 1\), register SW \(3\): is no longer running \(ready to switch on, ACT .*\) while commanded to run "
    r"at .*: most likely our own stop word given up unanswered at (\S+) \((\d+\.\d\d) s before this read: "
    r"CW \(0\) = 0x047E\) reached it late, after the start, and the drive stopped on that earlier stop "
    r"\(else another client wrote the same word\)$"
)


async def _proxy(tcp_sim) -> tuple[HoldingProxy, str]:
    """A proxy that holds the spin drive's first ramp stop word (its retry gets through)."""
    proxy = HoldingProxy(tcp_sim.endpoint.port, first_write(1, R.CW, CW_RAMP_STOP))
    return proxy, await proxy.start()


async def test_a_stop_word_given_up_that_stops_the_next_start_is_named_as_the_cause(tcp_sim):
    """Before the mend: 'is no longer running ...: stopped or changed by another client, or at the drive'."""
    proxy, url = await _proxy(tcp_sim)
    try:
        async with RigDrives(url, LIMITS, poll_interval=0.05, timeout=TIMEOUT, comm_loss_timeout=2.0) as r:
            await r.set_speeds(600 * RPM, 300 * RPM)
            await r.wait_settled(hold=0.05, timeout=5)
            wall0 = time.time()
            await r.stop(wait=True, timeout=5)  # the spin word given up after 0.5 s, its retry taken
            assert proxy.held and tcp_sim.regs(1)["ACT"] == 0
            await r.set_speeds(600 * RPM, 300 * RPM)  # started again: running, confirmed
            assert r.link.late.open([1]) and r.link.late.until([1]) is None  # in the window; no start's write
            words_before = len(tcp_sim.models[1].control_words)
            await proxy.release()  # the stale ramp stop word reaches the spin drive now
            with pytest.raises(DriveOffCommand) as info:
                await r.wait_settled(hold=5.0, timeout=5)
            with pytest.raises(DriveOffCommand):  # latched: no start undoes the poll's stop
                await r.set_speeds(600 * RPM, 300 * RPM)
            await tcp_sim.wait_stopped(timeout=5)
    finally:
        await proxy.aclose()
    words = str(info.value)
    m = re.fullmatch(LATE_STOP, words)
    assert m, words
    given_up = dt.datetime.fromisoformat(m[1].replace("Z", "+00:00")).timestamp()
    assert wall0 + TIMEOUT - 0.05 < given_up < wall0 + TIMEOUT + 1.0, (given_up - wall0, words)
    assert 0.0 < float(m[2]) < 2 * TIMEOUT, words  # read within the window
    assert info.value.drive == 1 and info.value.register == R.SW
    after = [cw for _, cw in tcp_sim.models[1].control_words][words_before:]
    assert after[0] == CW_RAMP_STOP and CW_RUN not in after, [hex(cw) for cw in after]  # not started again
    assert tcp_sim.regs(1)["REF"] == 0 and tcp_sim.regs(2)["REF"] == 0  # both stopped


def _status(cw: int, sw: int, ref: int, asked: float) -> DriveStatus:
    return DriveStatus("spin", 1, cw, 0.0, sw, 0.0, 0.0, 0, asked, reference_raw=ref, asked=asked)


RUNNING = int(R.SWBit.RDY_REF | R.SWBit.REMOTE)
NOT_RUNNING = int(R.SWBit.REMOTE)


def test_a_stop_word_given_up_is_the_cause_only_while_open_and_read_back():
    """The stop's words given up do not lengthen a stop's wait nor the exit's watch (`until`: a
    start's writes only), and are named only for a drive that reads back what they set."""
    late = LateWrites(timeout=0.1)
    late.note(1, R.CW, [CW_RAMP_STOP], stop=True)
    late.note(1, R.REF, [0], stop=True)
    now = time.monotonic()
    assert late.until([1]) is None and late.starts([1]) == [] and len(late.open([1])) == 2
    stopped = _status(CW_RAMP_STOP, NOT_RUNNING, 4000, now)
    assert "CW (0) = 0x047E)" in (stopped_late(stopped, late) or "")
    at_zero = _status(CW_RUN, RUNNING, 0, now)  # the zero reference arrived late: running to REF 0
    assert "REF (1) = 0x0000)" in (stopped_late(at_zero, late) or "")
    assert stopped_late(_status(CW_RUN, RUNNING, 2000, now), late) is None  # another REF: not a stop's doing
    assert stopped_late(_status(R.CW_READY, NOT_RUNNING, 4000, now), late) is None  # another word in CW
    assert stopped_late(_status(CW_RAMP_STOP, NOT_RUNNING, 4000, now + 0.25), late) is None  # window over
    orbit = DriveStatus("orbit", 2, CW_RAMP_STOP, 0.0, NOT_RUNNING, 0.0, 0.0, 0, now, asked=now)
    assert stopped_late(orbit, late) is None  # another drive's writes are its own


def test_a_zero_reference_given_up_read_back_is_said_as_one_the_drive_still_runs_at():
    """A stop's zero reference (REF) given up, read back on a drive still running: named as our
    stop's zero reference the drive runs at, not as a stop word it stopped on (before the mend:
    'our own stop word ... and the drive stopped on that earlier stop'); with its stop word in CW
    read back too, the stop word as before."""
    late = LateWrites(timeout=0.1)
    late.note(1, R.REF, [0], stop=True)
    now = time.monotonic()
    words = stopped_late(_status(CW_RUN, RUNNING, 0, now), late) or ""
    assert re.fullmatch(
        r"most likely our own stop's zero reference \(REF\) given up unanswered at \S+ \(\d+\.\d\d s before this "
        r"read: REF \(1\) = 0x0000\) reached it late, after the start, and the drive runs at REF 0 from that "
        r"earlier stop \(else another client wrote the same word\)",
        words,
    ), words
    late.note(1, R.CW, [CW_RAMP_STOP], stop=True)
    both = stopped_late(_status(CW_RAMP_STOP, NOT_RUNNING, 0, time.monotonic()), late) or ""
    assert "our own stop word given up" in both and "the drive stopped on that earlier stop" in both, both
    assert "REF (1) = 0x0000, CW (0) = 0x047E)" in both, both


def test_a_starts_write_given_up_is_named_beside_another_client_as_before():
    late = LateWrites(timeout=0.1)
    late.note(1, R.REF, [4000])
    assert late.until([1]) is not None
    assert stopped_late(_status(CW_RAMP_STOP, NOT_RUNNING, 4000, time.monotonic()), late) is None
