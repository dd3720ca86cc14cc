"""The free-space check before a point, never waited on by a request (RunControl.hold_for_room).

The check reads the disk (statvfs: a hung network share can hang it), on a daemon thread of its
own, off the loop (a thread that never returns holds neither the loop nor the process's exit).
While it runs, a plain stop ends the wait at once (StopRun: the run stops as asked, the drives
ramp to zero), and while nobody can answer (the unanswered limit, orbitrig.run.unanswered) a check
that has not returned within that limit stops the run as a pause nobody answers does; an abort or
a signal's stop cancel the run as ever. The check left behind is not waited for; should it fail
later, its exception is read (`_read`) and goes no further.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import threading
import time
from typing import Callable, TypeVar

from drives.waits import done_or_set

from orbitrig.run.control import StopRun
from orbitrig.run.unanswered import UNANSWERED

T = TypeVar("T")


async def checked(control, problem: Callable[[], str | None]) -> str | None:
    """`problem()` (why the disk has no room, or None) from its thread, unless `control` (RunControl)
    is asked a stop first or nobody can answer it for its unanswered limit: StopRun."""
    check = asyncio.wrap_future(on_daemon_thread(problem, "free-space-check"))
    check.add_done_callback(_read)  # a check given up on that fails later: its exception read, not logged
    t0 = time.monotonic()
    while True:
        control.wake.clear()
        if control.stop_requested:
            raise StopRun
        limit, deadline = control.unanswered.limit, control.unanswered.deadline_of(t0)
        if limit is not None and deadline is not None and time.monotonic() >= deadline:
            why = f"nobody can answer (the free-space check of the disk has not returned for {limit:g} s)"
            control.stop_unanswered(f"{UNANSWERED} ({why})", why)
            raise StopRun
        left = None if deadline is None else deadline - time.monotonic()
        if await done_or_set(check, control.wake, timeout=left) is check:
            return check.result()


def _read(check: asyncio.Future) -> None:
    """Read the exception of a finished check, so that one nobody awaits any more (given up on)
    is not logged as "Future exception was never retrieved" when collected."""
    if not check.cancelled():
        check.exception()


def on_daemon_thread(call: Callable[[], T], name: str) -> concurrent.futures.Future[T]:
    """`call()` on a daemon thread of its own named `name`: its future (its result or its
    exception). A thread that never returns holds neither the loop nor the process's exit; a
    future cancelled before the thread began leaves `call` uncalled."""
    done: concurrent.futures.Future[T] = concurrent.futures.Future()

    def run() -> None:
        if not done.set_running_or_notify_cancel():  # given up on before the thread began
            return
        try:
            done.set_result(call())
        except BaseException as err:  # noqa: BLE001 - raised where the future is awaited
            done.set_exception(err)

    threading.Thread(target=run, name=name, daemon=True).start()
    return done
