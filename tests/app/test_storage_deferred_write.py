"""A block's write waits until the next speeds are reached (`Background.defer_writes`, then
`resume_writes` at the ramps' expected end), at most DEFER_S: the storage thread no longer builds
the block's file while the command's reads and write, and the status read that starts the settle
hold, wait for the interpreter lock. The writes behind it wait too (the order on disk never
changes), and nothing waits longer than DEFER_S when no command comes (the last block of a
point, a stop, a fault)."""

from __future__ import annotations

import asyncio
import time

import pytest

from orbitrig.run import background
from orbitrig.run.background import DEFER_S, Background

pytestmark = pytest.mark.timeout(30)


async def test_a_deferred_write_starts_once_resumed_and_the_order_is_kept(monkeypatch):
    # the longest wait made 10 x DEFER_S here: a busy machine's late resume (and the storage
    # thread's start) stays far from it, so a write the resume released is told from one timed out
    longest = 10 * DEFER_S
    monkeypatch.setattr(background, "DEFER_S", longest)
    bg, started = Background({}), []
    bg.defer_writes()
    t0 = time.monotonic()
    for tag in ("03_fwd", "02_fwd"):
        bg.spawn(bg.write(lambda tag=tag: started.append((tag, time.monotonic() - t0))), f"store {tag}")
    await asyncio.sleep(DEFER_S / 5)
    assert started == []  # the command is still going out
    resumed = time.monotonic() - t0
    bg.resume_writes()
    await bg.settle()
    assert [tag for tag, _ in started] == ["03_fwd", "02_fwd"]
    assert all(resumed <= t < longest for _, t in started), (started, resumed)


async def test_a_deferred_write_waits_no_longer_than_defer_s_without_a_command():
    bg, started = Background({}), []
    bg.defer_writes()
    t0 = time.monotonic()
    bg.spawn(bg.write(lambda: started.append(time.monotonic() - t0)), "store 19_bwd")
    await bg.settle()
    assert DEFER_S <= started[0] < DEFER_S + 0.1, started


async def test_writes_are_not_deferred_unless_asked():
    bg, started = Background({}), []
    t0 = time.monotonic()
    bg.spawn(bg.write(lambda: started.append(time.monotonic() - t0)), "begin point 0000")
    await bg.settle()
    assert started[0] < DEFER_S / 2, started


async def test_a_write_resumed_at_a_time_starts_then_and_a_new_deferral_cancels_it():
    bg, started = Background({}), []
    bg.defer_writes()
    t0 = time.monotonic()
    bg.resume_writes(at=t0 + DEFER_S / 2)
    bg.spawn(bg.write(lambda: started.append(time.monotonic() - t0)), "store 04_fwd")
    await bg.settle()
    assert DEFER_S / 2 <= started[0] < DEFER_S, started  # at the time asked, not at once nor at DEFER_S
    bg.resume_writes(at=time.monotonic() + DEFER_S / 4)
    bg.defer_writes()  # the next block stored before that time: its write waits again
    t0 = time.monotonic()
    bg.spawn(bg.write(lambda: started.append(time.monotonic() - t0)), "store 05_fwd")
    await bg.settle()
    assert DEFER_S <= started[1] < DEFER_S + 0.1, started
    bg.resume_writes(at=time.monotonic() - 1.0)  # a time past: at once
    t0 = time.monotonic()
    bg.spawn(bg.write(lambda: started.append(time.monotonic() - t0)), "store 06_fwd")
    await bg.settle()
    assert started[2] < DEFER_S / 2, started
