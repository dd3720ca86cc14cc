"""The one timestamp format, the units at the edges and the rig's closed sets of words."""

from __future__ import annotations

import asyncio
import datetime as dt
import logging
import math
import random
import re

import pytest

from daq.backoff import Backoff
from orbitrig.load_systems import LMS, LoadSystem
from orbitrig.service.reconnect import reconnecting
from reduction.whirl import Directions, Whirl
from rigunits import MPA, RPM, format_duration, now_iso, record_stamp, utc_iso, utc_stamp

STAMP = re.compile(r"^\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3}Z$")


def test_one_utc_timestamp_format() -> None:
    assert utc_iso(0.0) == "1970-01-01T00:00:00.000Z"
    assert utc_iso(1.2345) == "1970-01-01T00:00:01.234Z"
    plus_two = dt.datetime(2026, 11, 27, 3, 30, 5, 123456, tzinfo=dt.timezone(dt.timedelta(hours=2)))
    assert utc_iso(plus_two) == "2026-11-27T01:30:05.123Z"  # any zone comes out in UTC
    assert utc_stamp(plus_two) == "20261127T013005.123Z"
    assert record_stamp(plus_two) == "2026-11-27T013005Z"  # a calibration record's name, to the second
    assert STAMP.match(now_iso())
    assert dt.datetime.fromisoformat(now_iso()).tzinfo == dt.timezone.utc  # Python reads it back as UTC
    before, t = dt.datetime.now(dt.timezone.utc), dt.datetime.fromisoformat(now_iso())
    assert abs((t - before).total_seconds()) < 5.0


def test_units_and_durations() -> None:
    assert math.isclose(3000 * RPM, 100 * math.pi)
    assert MPA == 1e6
    assert format_duration(59.6) == "1:00"
    assert format_duration(3 * 3600 + 62) == "3:01:02"
    assert format_duration(202, hours=True) == "0:03:22"  # a column of times: h:mm:ss always
    assert format_duration(3 * 3600 + 62, hours=True) == "3:01:02"


def test_closed_sets_keep_their_words() -> None:
    assert [str(w) for w in Whirl] == ["forward", "backward"]
    assert (Whirl.FORWARD.sign, Whirl.BACKWARD.sign) == (1, -1)
    assert Whirl.of(-3.0) is Whirl.BACKWARD and Whirl.of(0.1) is Whirl.FORWARD
    assert LMS == ("piezo", "strain") and LoadSystem("strain") is LoadSystem.STRAIN
    assert f"fx_{LoadSystem.PIEZO}" == "fx_piezo"


def test_directions_of_a_list_name_its_blocks_and_whirls() -> None:
    assert [str(d) for d in Directions] == ["forward", "backward", "both"]
    assert Directions.of(["backward", "forward"]) is Directions.BOTH
    assert Directions.of([Whirl.BACKWARD, Whirl.BACKWARD]) is Directions.BACKWARD
    assert [d.blocks for d in Directions] == [1, 1, 2]
    assert Directions.BOTH.whirls == (Whirl.FORWARD, Whirl.BACKWARD)  # forward first
    assert Directions("backward").whirls == (Whirl.BACKWARD,)
    with pytest.raises(ValueError):
        Directions.of([])
    with pytest.raises(ValueError):
        Directions.of(["sideways"])


def test_reconnecting_backs_off_with_jitter_and_resets_after_traffic() -> None:
    carried = [False, False, False, True, False]
    calls: list[float] = []
    sleeps: list[float] = []
    backoff = Backoff(0.01, 0.04, rng=random.Random(1))
    original = backoff.next_delay

    def recorded() -> float:
        sleeps.append(original())
        return sleeps[-1]

    backoff.next_delay = recorded  # type: ignore[method-assign]

    async def session() -> bool:
        calls.append(len(calls))
        return carried[len(calls) - 1]

    asyncio.run(reconnecting(session, backoff, logging.getLogger("test"), stop=lambda: len(calls) == len(carried)))
    assert len(calls) == len(carried) and len(sleeps) == len(carried) - 1  # no wait after the last
    ceilings = [0.01, 0.02, 0.04, 0.01]  # doubling to the maximum; back to the start after traffic
    assert all(c / 2 <= s <= c for s, c in zip(sleeps, ceilings)), sleeps
    assert len(set(sleeps)) == len(sleeps)  # jittered


def test_planned_frequencies_read_as_the_decimals_meant() -> None:
    """Every ratio 0.01 .. 3 at 100 .. 6000 rpm whose ratio x rpm / 60 is a short decimal reads as
    that decimal in Hz, computed as the plan does (ratio x (rpm x RPM) rad/s); the plain quotient
    misses 8501 of the 19900 (4.999999999999999)."""
    from fractions import Fraction

    import numpy as np

    from rigunits import in_hz

    ratios = [round(0.01 * k, 12) for k in range(1, 301)]
    checked = plain_missed = 0
    for rpm in range(100, 6001, 50):
        omega = np.array([r * (rpm * RPM) for r in ratios])
        for r, hz, plain in zip(ratios, in_hz(omega), omega / (2 * math.pi)):
            meant = Fraction(str(r)) * rpm / 60
            if Fraction(f"{float(meant):.12g}") != meant:
                continue  # 10/3 Hz: no short decimal to read as
            checked += 1
            assert hz == float(meant), (r, rpm, hz)
            plain_missed += plain != float(meant)
    assert checked > 19000 and plain_missed > checked / 3, (checked, plain_missed)


#: a second owner of a conversion at the edges: rad/s over 2 pi (Hz), 2 pi times a frequency in Hz,
#: a length times 1e6 written as 'um', a pressure over 1e6 written as MPa (rigunits.HZ / in_hz,
#: rigunits.micrometres and rigunits.MPA own them)
_OWN_CONVERSION = re.compile(
    r"/ \(2(\.0)? \* (np|math)\.pi\)|\b2(\.0)? \* (np|math)\.pi \* [^,)\n]*hz"
    r"|1e6[^}\n]*\} ?um\b|/ 1e6[^}\n]*\} ?MPa\b",
    re.IGNORECASE,
)


def own_conversions(text: str) -> list[str]:
    """'LINE: text' of every line of Python source `text` that converts to Hz, micrometres or MPa itself."""
    return [f"{n}: {line.strip()}" for n, line in enumerate(text.splitlines(), 1) if _OWN_CONVERSION.search(line)]


def test_the_application_converts_at_the_edges_through_rigunits() -> None:
    from support.paths import ROOT

    sample = [
        "a = w / (2 * np.pi)",
        'b = 2 * math.pi * col["orbit_hz"]',
        'c = f"{r * 1e6:g} um"',
        "d = slots * (2 * np.pi / 360)",  # an angle of slots is no frequency
        'e = f"pr = {p / 1e6:.4g} MPa"',
    ]
    assert own_conversions("\n".join(sample)) == [f"{n}: {sample[n - 1]}" for n in (1, 2, 3, 5)]
    found = {
        str(p.relative_to(ROOT)): hits
        for p in sorted((ROOT / "orbitrig").rglob("*.py"))
        if (hits := own_conversions(p.read_text(encoding="utf-8")))
    }
    assert found == {}


def test_a_set_speed_reads_one_way() -> None:
    """A commanded speed is said as the plan's decimal (rigunits.rpm_text), in the step that sets it
    as in the run's note that it was set: an orbit of ratio 0.569 at 1000 rpm is '+569 rpm' in both."""
    from orbitrig.run.steps import Block, SetOrbit, SetSpin
    from rigunits import rpm_text

    spin = 1000 * RPM
    assert (rpm_text(spin), rpm_text(20.5 * RPM), rpm_text(-0.0, signed=True)) == ("1000 rpm", "20.5 rpm", "+0 rpm")
    assert rpm_text(-0.977778 * spin, signed=True) == "-977.778 rpm"  # the planned ratio's decimal, not -977.8
    block = Block(2, +1, 0.569 * spin)
    assert SetSpin(0, 1.0, spin, block.orbit).describe() == "set spin 1000 rpm (orbit +569 rpm)"
    assert SetOrbit(0, 1.0, block).describe() == "set orbit +569 rpm [02_fwd]"
