"""Storage and identification in the background, overlapping the next motion.

Writes run in one storage thread, one at a time, in submission order (a FIFO
lock), so a block is never written after the point that holds it is marked
complete; the same thread makes every write, so the order of the syscalls on
disk is the order of submission. What is in flight is never cut off: after a stop or an abort
the engine waits for it once the drives are stopped (`settle`), never before.
No write follows a failed one. The first failure is reported at once to `on_failure` (the engine ends the
run: drives to a safe stop first) and raised by `check`.

A block's write waits until the next speeds' first status is read (`defer_writes` as the block is
stored, `resume_writes(at=...)` by the settle: the ramps' expected end and a margin; at most DEFER_S):
the storage thread builds the block's file holding the interpreter lock for milliseconds at a time,
and the command's reads and write, then the poll that starts the settle hold, waited for it (a speed
command took 9 to 19 ms instead of 4; that poll began up to 7 ms late). The writes behind it wait
too: the order on disk never changes, and nothing waits longer than DEFER_S. While it or the
identification runs Python, every orbitrig command's interpreter hands its lock to the loop within
1 ms (orbitrig/cli/threads.py).

A point's records (its blocks: raw counts, means, phasors) stay in memory until the
point is identified, stored and complete. At most POINTS_IN_FLIGHT earlier points may
still be on their way when the next one begins (`wait_for_points`): a machine that
identifies more slowly than the rig measures (a loaded computer, a simulator at a high
speed-up) makes the run wait between points instead of piling records up. A point
identified before the one measured ahead of it has its result published after that one's
(`earlier_points_done`): the results go out in point order.
"""

from __future__ import annotations

import asyncio
import itertools
import logging
import time
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from collections.abc import Callable, Coroutine
from typing import TypeVar

from drives.waits import first_set
from orbitrig.run.events import RunFailed
from orbitrig.store.errors import StorageError

log = logging.getLogger(__name__)
T = TypeVar("T")
POINTS_IN_FLIGHT = 1  # earlier points still identified or stored while the next one is measured
DEFER_S = 0.1  # wall s at most that a deferred write waits for `resume_writes`
BACKLOG_NOTE_S = 30.0  # wall s of waiting for them between two notes of it
STORAGE_THREAD = ThreadPoolExecutor(max_workers=1, thread_name_prefix="orbitrig-storage")  # started on first use


async def to_the_end(fn: Callable[..., T], *args: object) -> T:
    """``fn(*args)`` in the storage thread (after every write submitted before it), off the event
    loop, waited for to its end even if this wait is cancelled; a cancellation is raised once
    it has ended."""
    future = asyncio.get_running_loop().run_in_executor(STORAGE_THREAD, fn, *args)
    cancelled = False
    while not future.done():
        try:
            await asyncio.wait({future})
        except asyncio.CancelledError:
            cancelled = True
    if cancelled:
        raise asyncio.CancelledError
    return future.result()


class Background:
    def __init__(self, timing: dict[str, float], on_failure: Callable[[BaseException], None] | None = None):
        self.timing = timing
        self._on_failure = on_failure
        self._pending: dict[asyncio.Task[object], None] = {}  # in the order spawned
        self._points: deque[asyncio.Task[object]] = deque()  # each point's completion, oldest first
        self._writes = asyncio.Lock()
        self._write_error: Exception | None = None  # the first write that failed
        self._writing_since: float | None = None  # time.monotonic() the write in the storage thread began
        self._resumed = asyncio.Event()  # set: writes start at once (`defer_writes`)
        self._resumed.set()
        self._resume_timer: asyncio.TimerHandle | None = None  # `resume_writes(at=...)` waiting
        self.error: BaseException | None = None
        self._failed: str = ""  # the name of the task that failed first ('identify point 0002')

    async def write(self, fn: Callable[..., T], *args: object) -> T:
        """One storage write, in a thread, after every write submitted before it; none after one
        that failed (the run ends at the failed write, and a write already queued behind it,
        e.g. the next block measured meanwhile, raises RunFailed without touching the disk)."""
        async with self._writes:
            if not self._resumed.is_set():
                await first_set(self._resumed, timeout=DEFER_S)
            if self._write_error is not None:
                raise RunFailed("not written: an earlier storage write failed") from self._write_error
            t = self._writing_since = time.monotonic()
            try:
                return await asyncio.get_running_loop().run_in_executor(STORAGE_THREAD, fn, *args)
            except Exception as err:  # recorded before the lock passes to the next write
                self._write_error = err
                raise
            finally:
                self._writing_since = None
                self.timing["store"] = self.timing.get("store", 0.0) + time.monotonic() - t

    def write_stalled_s(self) -> float:
        """Wall s the write in the storage thread has been going on (0 with none)."""
        since = self._writing_since
        return 0.0 if since is None else time.monotonic() - since

    def defer_writes(self) -> None:
        """Writes from now on wait for `resume_writes`, at most DEFER_S wall s each (a speed command
        about to go out)."""
        self._cancel_timer()
        self._resumed.clear()

    def resume_writes(self, at: float | None = None) -> None:
        """Writes start again at once, or at `at` (monotonic s: the drives' ramps expected over and
        their first status read; a write asked DEFER_S before that starts then all the same)."""
        self._cancel_timer()
        delay = 0.0 if at is None else at - time.monotonic()
        if delay > 0:
            self._resume_timer = asyncio.get_running_loop().call_later(delay, self._resumed.set)
        else:
            self._resumed.set()

    def _cancel_timer(self) -> None:
        if self._resume_timer is not None:
            self._resume_timer.cancel()
            self._resume_timer = None

    def spawn(self, coro: Coroutine[object, object, T], name: str) -> asyncio.Task[T]:
        task = asyncio.ensure_future(coro)
        task.set_name(name)
        self._pending[task] = None
        task.add_done_callback(self._done)
        return task

    def spawn_point(self, coro: Coroutine[object, object, object], name: str) -> None:
        """A point's completion (identified, stored, committed): counted by `wait_for_points`."""
        self._points.append(self.spawn(coro, name))

    async def earlier_points_done(self) -> None:
        """Wait until every point completion spawned before the calling one is done (their
        failures are their own): results are published in the order the points were measured."""
        me = asyncio.current_task()
        earlier = {t for t in itertools.takewhile(lambda t: t is not me, self._points) if not t.done()}
        if earlier:
            await asyncio.wait(earlier)

    async def wait_for_points(self, limit: int = POINTS_IN_FLIGHT, note: Callable[[str], None] | None = None) -> None:
        """Wait until at most `limit` points are still on their way to completion (none is
        cancelled, even if this wait is); the seconds waited count as timing["backlog"]. Every
        BACKLOG_NOTE_S wall s of waiting `note` is told how long (a stalled disk says so)."""
        t = time.monotonic()
        while self._points:
            if self._points[0].done():
                self._points.popleft()
            elif len(self._points) > limit:
                done, _ = await asyncio.wait({self._points[0]}, timeout=BACKLOG_NOTE_S)
                if not done and note is not None:
                    note(
                        f"waiting for {self._points[0].get_name()} (identified and stored in the background) "
                        f"for {time.monotonic() - t:.0f} s: a slow or stalled disk, or a loaded computer"
                    )
            else:
                break
        self.timing["backlog"] = self.timing.get("backlog", 0.0) + time.monotonic() - t

    def oldest_point(self) -> str | None:
        """The name of the oldest point still on its way to completion ('complete point 0002'), or None."""
        pending = [t for t in self._points if not t.done()]
        return pending[0].get_name() if pending else None

    def _done(self, task: asyncio.Task[object]) -> None:
        self._pending.pop(task, None)
        error = None if task.cancelled() else task.exception()
        if error is not None and self.error is None:
            self.error, self._failed = error, task.get_name()
            bug = not isinstance(error, (StorageError, OSError, RunFailed))  # a bug: its traceback is kept
            log.error("%s failed: %s", self._failed, error, exc_info=error if bug else None)
            if self._on_failure is not None:
                self._on_failure(error)

    def failure_message(self) -> str | None:
        """What failed in the background, for the operator (None: nothing failed)."""
        err = self.error
        if err is None:
            return None
        if isinstance(err, (StorageError, OSError)):  # the error names the file
            return f"storage failed: {type(err).__name__}: {err}"
        return f"{self._failed} failed: {type(err).__name__}: {err}"  # 'identify point 0002 failed: ...'

    def check(self) -> None:
        """Raise RunFailed if a background task failed."""
        if (message := self.failure_message()) is not None:
            raise RunFailed(message) from self.error

    def in_flight(self) -> list[str]:
        """The names of the writes and identifications not finished yet, oldest first
        ('store 0002/f03', 'identify point 0002', 'complete point 0002')."""
        return [task.get_name() for task in self._pending]

    async def settle(self, timeout: float | None = None) -> bool:
        """Wait for everything in flight, at most `timeout` s (None: to its end), not cancelling
        it, even if this wait is cancelled; whether nothing is left in flight."""
        end = None if timeout is None else time.monotonic() + timeout
        while self._pending:
            left = None if end is None else end - time.monotonic()
            if left is not None and left <= 0:
                return False
            await asyncio.wait(set(self._pending), timeout=left)
        return True

    async def drain(self) -> None:
        """Wait for everything in flight, then raise its first failure."""
        await self.settle()
        self.check()
