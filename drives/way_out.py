"""How the rig's exit went before its stop: cancelled, or failed (`RigDrives.__aexit__`); its
waits before the stop (`starved_outcome`, `end_poll`).

Nothing the exit does before its stop may skip it: a cancellation there is counted, any other
exception (a bug, an unexpected error of the poll or the link) is logged with its traceback
and kept; both drives' stop then goes out, the link is closed, and what was kept is raised
(`end`): a cancellation first, else the failure, unless the block itself raised (then its
exception goes on, the failure noted on it). A KeyboardInterrupt or SystemExit is always raised.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections.abc import Iterator
from typing import TYPE_CHECKING

from drives.poll_pace import read_again_by
from drives.waits import first_set

if TYPE_CHECKING:
    from drives.poll import DrivePoll

log = logging.getLogger(__name__)

#: wall s the exit waits for the cancelled poll to end before it stops the drives anyway
POLL_END_S = 1.0


class WayOut:
    """The cancellations and the first failure met by an exit before its stop."""

    def __init__(self) -> None:
        self.cancelled = False
        self.failure: BaseException | None = None

    @contextlib.contextmanager
    def caught(self, what: str) -> Iterator[None]:
        """A context whose exception is kept, not raised: `what` it was doing, for the log."""
        try:
            yield
        except asyncio.CancelledError:
            self.cancelled = True
        except BaseException as err:  # noqa: BLE001 - raised by `end`, after the stop
            self.failed(err, what)

    def failed(self, err: BaseException, what: str) -> None:
        """Keep `err` (the first one) and log it with its traceback."""
        log.error("%s failed: %r; stopping both drives", what, err, exc_info=err)
        if self.failure is None:
            self.failure = err

    def end(self, exc: BaseException | None) -> None:
        """After the stop and the close: raise the cancellation, or the failure (`exc`: what the
        block raised, which goes on instead, the failure noted on it)."""
        failure = self.failure
        if self.cancelled and failure is not None:
            raise asyncio.CancelledError from failure
        if self.cancelled:
            raise asyncio.CancelledError
        if failure is None:
            return
        if exc is None or not isinstance(failure, Exception):
            raise failure
        exc.add_note(f"then the drives' exit failed: {failure!r} (logged); both drives stopped")


async def end_poll(poll: DrivePoll, task: asyncio.Task[None], way: WayOut) -> None:
    """Cancel the poll's `task` and wait for its end (POLL_END_S at most: the stop never waits on it,
    it would feed the watchdogs); a poll that had ended on an exception is the exit's failure."""
    task.cancel()
    with way.caught("the wait for the poll's end"):
        await asyncio.wait([task], timeout=POLL_END_S)  # cancelled again: stop the drives first
    died: BaseException | None = poll.crashed  # recorded by the poll: the cancel may overtake its end
    if not task.done():
        log.error("the drives' poll did not end %g s after its cancel: stopping them beside it", POLL_END_S)
    elif died is None and not task.cancelled():
        died = task.exception()
    if died is not None:
        way.failed(died, "the drives' poll")


async def starved_outcome(poll: DrivePoll, timeout: float) -> None:
    """Before the poll ends: a drive whose comm-loss watchdog is being starved (drives/starve.py)
    is waited for until the poll has read it again and recorded what it shows, at most its
    starving's end + two polls + a request's `timeout`, the other drive polled on meanwhile."""
    due = poll.starver.due()
    if due is None:
        return
    deadline = read_again_by(due, poll.poll_interval, timeout)
    log.warning("closing in up to %.1f s: the starved drive is read again first", deadline - time.monotonic())
    while poll.starver.due() is not None and time.monotonic() < deadline and poll.crashed is None:
        await first_set(poll.tick, timeout=deadline - time.monotonic())
