"""The starver's judgement over a sequence of polls (drives/starve.py), on statuses as a poll
reads them: when a drive found running on through the stop is starved, and what forgives it.
The live behaviour (real Modbus, the watchdog tripping) is tests/drives/test_stop_refused_watchdog_starved.py."""

from __future__ import annotations

import time

from drives import registers as R
from drives.drive import Drive, DriveParameters, DriveStatus
from drives.link import ModbusLink
from drives.starve import Starver

POLL_S, WATCHDOG_S, REF_1000RPM = 0.05, 0.5, 8333
PARAMS = DriveParameters(
    speed_scale=251.3,
    max_speed=314.2,
    accel_time=1.0,
    decel_time=1.0,
    comm_loss_timeout=WATCHDOG_S,
    at_setpoint_band=1.0,
)


def starver() -> tuple[Starver, ModbusLink]:
    link = ModbusLink("tcp://127.0.0.1:1")  # never connected: the starver only names what it may not address
    drives = [Drive(link, i, n, bidirectional=True) for i, n in ((1, "spin"), (2, "orbit"))]
    for d in drives:
        d.params = PARAMS
    return Starver(link, drives, POLL_S), link


def read(t: float, *, spin_running: bool = True) -> list[DriveStatus]:
    """A poll at monotonic `t` s: the spin drive running on at 1000 rpm (or ramping down,
    OFF1 active), the orbit drive stopped."""
    word, raw = (int(R.SWBit.RDY_REF), REF_1000RPM) if spin_running else (0, 0)
    spin = DriveStatus("spin", 1, R.CW_RUN, raw * 1e-3, word, raw * 1e-3, 0.0, 0, t, raw, raw)
    orbit = DriveStatus("orbit", 2, R.CW_RAMP_STOP, 0.0, 0, 0.0, 0.0, 0, t, 0, 0)
    return [spin, orbit]


def stopped() -> tuple[Starver, ModbusLink, float]:
    """A starver whose first stop since the command has just ended; monotonic s of that end."""
    s, link = starver()
    s.stop_ended()
    return s, link, time.monotonic()


def test_defiant_for_two_polls_is_starved():
    s, link, t = stopped()
    assert s.judge(read(t + 0.01), took=True) == []  # found running: defiant from now
    assert s.judge(read(t + 0.06), took=True) == [] and link.unaddressed == {}
    found = s.judge(read(t + 0.12), took=True)
    assert len(found) == 1 and found[0].drive == 1 and "trips fault 7510" in str(found[0])
    assert set(link.unaddressed) == {1}


def test_reads_before_the_first_stop_ended_are_not_judged():
    """Running at the command, or read while the first stop was still on its way: not defiant."""
    s, link = starver()
    assert s.judge(read(time.monotonic()), took=False) == []
    s.stop_ended()
    t = time.monotonic()
    assert s.judge(read(t - 0.3), took=False) == [] and s.judge(read(t - 0.01), took=False) == []
    assert s.judge(read(t + 0.01), took=False) == []  # the first read after it: defiant from here
    assert [e.drive for e in s.judge(read(t + 0.12), took=False)] == [1]


def test_a_later_stop_does_not_restart_the_clock():
    """Stops pressed again and again: each ends after the poll's read, yet the drive found defiant
    after the first is starved two polls after that finding."""
    s, link, t = stopped()
    s.judge(read(t + 0.01), took=True)
    for _ in range(5):
        s.stop_ended()  # the operator's next press
    assert [e.drive for e in s.judge(read(t + 0.12), took=True)] == [1] and set(link.unaddressed) == {1}


def test_a_poll_reading_it_stopping_forgives_it():
    s, link, t = stopped()
    s.judge(read(t + 0.01), took=True)
    assert s.judge(read(t + 0.06, spin_running=False), took=True) == []  # ramping down, OFF1 active
    assert s.judge(read(t + 0.11), took=True) == []  # running again: judged afresh, defiant from here
    assert s.judge(read(t + 0.16), took=True) == [] and link.unaddressed == {}
    assert [e.drive for e in s.judge(read(t + 0.22), took=True)] == [1]


def test_a_speed_commanded_clears_the_clock():
    s, link, t = stopped()
    s.judge(read(t + 0.01), took=True)
    s.reset()  # the next speed command: running is what it was told
    assert s.judge(read(t + 0.12), took=True) == [] and s.judge(read(t + 0.5), took=True) == []
    assert link.unaddressed == {}
