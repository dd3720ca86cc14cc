"""A block's write waits until the next speed command is out (`Background.defer_writes`, then
`resume_writes`), at most DEFER_S: the storage thread no longer builds the block's file while
the command's reads and write wait for the interpreter lock. The writes behind it wait too (the
order on disk never changes), and nothing waits longer than DEFER_S when no command comes (the
last block of a point, a stop, a fault)."""

from __future__ import annotations

import asyncio
import time

import pytest

from orbitrig.run.background import DEFER_S, Background

pytestmark = pytest.mark.timeout(30)


async def test_a_deferred_write_starts_once_resumed_and_the_order_is_kept():
    bg, started = Background({}), []
    bg.defer_writes()
    t0 = time.monotonic()
    for tag in ("03_fwd", "02_fwd"):
        bg.spawn(bg.write(lambda tag=tag: started.append((tag, time.monotonic() - t0))), f"store {tag}")
    await asyncio.sleep(DEFER_S / 5)
    assert started == []  # the command is still going out
    bg.resume_writes()
    await bg.settle()
    assert [tag for tag, _ in started] == ["03_fwd", "02_fwd"]
    assert all(DEFER_S / 5 <= t < DEFER_S for _, t in started), started


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
