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


# -- the emergency stop let through to a starved drive: judged on its speed, against its emergency ramp --

RUNNING = R.SWBit.RDY_ON | R.SWBit.RDY_RUN | R.SWBit.RDY_REF | R.SWBit.OFF_2_STA | R.SWBit.OFF_3_STA | R.SWBit.REMOTE
IN_OFF3 = R.SWBit.RDY_ON | R.SWBit.OFF_2_STA | R.SWBit.REMOTE  # OFF_3_STA 0: in its emergency ramp
ACT0 = 6667  # raw: 1000 rpm at SPEED_SCALE 3000 rpm
SLOW = DriveParameters(  # emergency ramp from 1000 rpm: DECEL_TIME / 10 x 1000 / 3000 = 0.5 s
    speed_scale=314.16, max_speed=314.16, accel_time=15.0, decel_time=15.0, comm_loss_timeout=3.0, at_setpoint_band=1.0
)
OFF3_RAMP_S = 0.5


def spin_read(t: float, raw: int, word: int = IN_OFF3) -> list[DriveStatus]:
    """A poll handled at monotonic `t`: the spin drive at raw ACT `raw` (status word `word`), the orbit drive stopped."""
    act = raw / 20000 * 314.16
    ref = raw if word == RUNNING else 0  # running on at its reference, or in the emergency stop's ramp
    spin = DriveStatus("spin", 1, R.CW_EMERGENCY_STOP, ref / 20000 * 314.16, int(word), act, 0.0, 0, t, ref, raw)
    orbit = DriveStatus("orbit", 2, R.CW_RAMP_STOP, 0.0, 0, 0.0, 0.0, 0, t, 0, 0)
    return [spin, orbit]


def lifted() -> tuple[Starver, ModbusLink, list[DriveStatus], float]:
    """The spin drive found running on at 1000 rpm, starved, then the emergency stop let through to
    it and taken; returns the starver, its link, the poll's stand-in read (before the word) and the
    monotonic s the word was taken; `ramp_end` is that + 0.5 s + two polls + the request timeout."""
    s, link = starver()
    for d in s.drives:
        d.params = SLOW
    s.stop_ended()
    t = time.monotonic()
    s.judge(spin_read(t + 0.01, ACT0, RUNNING), took=True)
    assert [e.drive for e in s.judge(spin_read(t + 0.12, ACT0, RUNNING), took=True)] == [1]
    stand_in = [s.starved(s.drives[0]), spin_read(t + 0.12, 0)[1]]
    assert stand_in[0] is not None and set(link.unaddressed) == {1}
    time.sleep(max(0.0, t + 0.13 - time.monotonic()))  # the emergency stop comes after that read
    with s.lifting()(s.drives[0]):
        assert link.unaddressed == {}  # the OFF3 word goes to it
    return s, link, stand_in, time.monotonic()


def test_the_stand_in_read_before_the_emergency_stop_is_not_judged():
    """A poll that began while the drive was starved reads its stand-in (the last status, running, read
    before the word); the OFF3 is taken while that poll reads the other drive: the stand-in says
    nothing of the emergency ramp, so it is not starved again; the next poll's read decides."""
    s, link, stand_in, t0 = lifted()
    assert s.outcome(stand_in, asked=t0 - 0.02) == [] and link.unaddressed == {}
    found = s.outcome(spin_read(t0 + 0.06, 0), asked=t0 + 0.05)
    assert len(found) == 1 and "stopped by its emergency ramp" in str(found[0]) and link.unaddressed == {}


def test_a_read_handled_late_while_slowing_in_the_emergency_ramp_is_not_starved_again():
    """A poll asked 0.1 s after the word reads the drive 20 % down its 0.5 s emergency ramp, but a busy host
    handles the answer past `ramp_end` (the word + 0.5 s + two polls + the 1 s request timeout): its speed
    is judged as of the poll's start, where the ramp puts it, so it is read on, not starved again."""
    s, link, _, t0 = lifted()
    late = t0 + OFF3_RAMP_S + 2 * POLL_S + link.timeout + 0.3
    assert s.outcome(spin_read(late, int(ACT0 * 0.8)), asked=t0 + 0.1) == [] and link.unaddressed == {}
    found = s.outcome(spin_read(late + 0.05, 0), asked=late + 0.01)
    assert len(found) == 1 and "stopped by its emergency ramp" in str(found[0])


def test_a_drive_not_slowing_in_its_emergency_ramp_is_starved_again_in_time():
    """In OFF_3_STA 0 but holding its speed: read on while the ramp could still take it to zero by
    `ramp_end`, starved again from the first poll asked later than that (its watchdog fed no longer)."""
    s, link, _, t0 = lifted()
    slack = 2 * POLL_S + link.timeout  # ramp_end - t0 - OFF3_RAMP_S
    assert s.outcome(spin_read(t0 + 0.05, ACT0), asked=t0 + 0.04) == [] and link.unaddressed == {}
    assert s.outcome(spin_read(t0 + slack - 0.01, ACT0), asked=t0 + slack - 0.02) == [] and link.unaddressed == {}
    assert s.outcome(spin_read(t0 + slack + 0.03, ACT0), asked=t0 + slack + 0.02) == []
    assert set(link.unaddressed) == {1}  # starved again
    found = s.outcome(spin_read(t0 + slack + 0.08, ACT0), asked=t0 + slack + 0.07)
    assert found == [] and set(link.unaddressed) == {1}  # not addressed: the poll shows its last status


def test_a_drive_running_on_after_the_emergency_stop_is_starved_again_at_once():
    """It took the word and runs on (operation enabled, OFF_3_STA 1), early and within every bound: starved again."""
    s, link, _, t0 = lifted()
    assert s.outcome(spin_read(t0 + 0.02, ACT0, RUNNING), asked=t0 + 0.01) == [] and set(link.unaddressed) == {1}
