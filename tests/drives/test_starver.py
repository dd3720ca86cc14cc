"""The starver's judgement over a sequence of polls (drives/starve.py), on statuses as a poll
reads them: when a drive found running on through the stop is starved, and what forgives it.
The live behaviour (real Modbus, the watchdog tripping) is tests/drives/test_stop_refused_watchdog_starved.py."""

from __future__ import annotations

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


def test_defiant_for_two_polls_is_starved():
    s, link = starver()
    assert s.judge(read(1.0), took=True) == []  # found running: defiant from now
    assert s.judge(read(1.05), took=True) == [] and link.unaddressed == {}
    found = s.judge(read(1.1), took=True)
    assert len(found) == 1 and found[0].drive == 1 and "trips fault 7510" in str(found[0])
    assert set(link.unaddressed) == {1}


def test_polls_that_could_not_judge_keep_the_defiance():
    """Stops pressed again and again: polls in between meet a stop in flight (no judgement) and
    are handed to `forgive`; the drive they read still turning stays defiant and is starved on the
    first judged poll past its bound, not two polls after the presses end."""
    s, link = starver()
    s.judge(read(1.0), took=True)
    for t in (1.05, 1.1, 1.15, 1.2):
        s.forgive(read(t))
    found = s.judge(read(1.25), took=True)
    assert [e.drive for e in found] == [1] and set(link.unaddressed) == {1}


def test_a_poll_reading_it_stopping_forgives_it():
    s, link = starver()
    s.judge(read(1.0), took=True)
    s.forgive(read(1.05, spin_running=False))  # took the stop after all: ramping down, OFF1 active
    assert s.judge(read(1.1), took=True) == []  # running again: judged afresh, defiant from 1.1
    assert s.judge(read(1.15), took=True) == [] and link.unaddressed == {}
    assert [e.drive for e in s.judge(read(1.25), took=True)] == [1]
