"""The free-space check before a point hangs (statvfs on a network share that stopped answering):
a plain stop ends the wait at once (StopRun), and so, while nobody can answer, does the unanswered
limit, the run's stop saying why. Before, both waited for the check to return.

The run's own control and its own check (orbitrig.run.run_dir.no_room's statvfs, through the
store's free-space check on a real folder); os.statvfs is replaced by one that blocks until the
test lets it go: a hung share cannot be produced in CI (no FUSE, no NFS server), the one mock here;
the check that fails once given up on is a disk read hung and then failing (OSError), the same fault."""

from __future__ import annotations

import asyncio
import os
import threading
import time

import pytest

from orbitrig.run.control import RunControl, StopRun
from orbitrig.run.states import RUNNING, STOPPING

pytestmark = pytest.mark.timeout(30)

LIMIT_S = 0.5  # the unanswered limit here (wall s)
HUNG_S = 5.0  # how long the check hangs at most (then it is let go: the old code's wait ends)


@pytest.fixture
def hung_statvfs(monkeypatch, tmp_path):
    """A check that reads the disk through os.statvfs of `tmp_path`, hung until the test ends
    (HUNG_S at most); (the check, the Event set once statvfs was entered)."""
    release, entered, real = threading.Event(), threading.Event(), os.statvfs

    def hung(path):
        entered.set()
        release.wait(HUNG_S)
        return real(path)

    monkeypatch.setattr(os, "statvfs", hung)

    def problem() -> str | None:
        free = os.statvfs(tmp_path).f_bavail
        return None if free > 0 else "no room"

    yield problem, entered
    release.set()


def _control(stops: list[str]) -> RunControl:
    control = RunControl(lambda state, message: None, lambda note: None, stops.append)
    control.state = RUNNING
    return control


async def test_a_plain_stop_does_not_wait_for_a_hung_free_space_check(hung_statvfs):
    problem, entered = hung_statvfs
    control = _control([])
    held = asyncio.create_task(control.hold_for_room(problem))
    await asyncio.to_thread(entered.wait, 10)
    t0 = time.monotonic()
    control.request_stop("ada")
    with pytest.raises(StopRun):
        await asyncio.wait_for(held, HUNG_S + 5)
    assert time.monotonic() - t0 < 1.0
    assert control.state == STOPPING and control.stop_by == "ada"


async def test_nobody_to_answer_stops_the_run_after_the_limit_not_after_the_check(hung_statvfs):
    problem, entered = hung_statvfs
    stops: list[str] = []
    control = _control(stops)
    control.set_unanswered_limit(LIMIT_S)
    t0 = time.monotonic()
    with pytest.raises(StopRun):
        await asyncio.wait_for(control.hold_for_room(problem), HUNG_S + 5)
    took = time.monotonic() - t0
    assert entered.is_set() and LIMIT_S <= took < LIMIT_S + 1.0, took
    why = f"nobody can answer (the free-space check of the disk has not returned for {LIMIT_S:g} s)"
    assert stops == [f"orbitrig ({why})"] and control.stop_by == f"orbitrig ({why})"
    assert control.state == STOPPING


async def test_a_check_given_up_that_fails_later_leaves_no_unread_exception(caplog):
    """The disk read given up on (a plain stop) fails afterwards (statvfs's OSError, as a share
    that comes back refusing): its exception is read where the check was left, so asyncio logs no
    "Future exception was never retrieved" when the future is collected."""
    import gc

    release, entered = threading.Event(), threading.Event()

    def problem() -> str | None:
        entered.set()
        release.wait(HUNG_S)
        raise OSError(5, "Input/output error")

    control = _control([])
    held = asyncio.create_task(control.hold_for_room(problem))
    await asyncio.to_thread(entered.wait, 10)
    control.request_stop("ada")
    try:
        await asyncio.wait_for(held, HUNG_S + 5)
    except StopRun:
        pass
    del held
    (thread,) = [t for t in threading.enumerate() if t.name == "free-space-check"]
    release.set()
    await asyncio.to_thread(thread.join, 10)
    for _ in range(5):  # the thread's outcome reaches the loop's future
        await asyncio.sleep(0.01)
    with caplog.at_level("ERROR", logger="asyncio"):
        gc.collect()
    assert not thread.is_alive()
    assert [r for r in caplog.records if "never retrieved" in r.getMessage()] == []
