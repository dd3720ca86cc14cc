"""How the rig's exit went before its stop: cancelled, or failed (`RigDrives.__aexit__`).

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
from collections.abc import Iterator

log = logging.getLogger(__name__)


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
