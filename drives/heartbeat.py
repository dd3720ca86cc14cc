"""How many failed polls in a row declare the drive link lost, fitted under the drives' watchdog.

A drive trips (fault 7510) after COMM_LOSS_TIMEOUT s without a valid request. After a lost
request the longest silence is one request timeout plus one poll interval (`gap`); the link
must be declared lost (and the sweep's interlock act) before the watchdog trips the drives,
so `count` x `gap` is kept below the shortest watchdog.

`LinkSilence` bounds the time as well: failed polls are counted only as the poll gets the link,
and other requests hold it meanwhile (a stop's tries to both drives: 4 to 12 request timeouts
after a drop), so `count` failed polls can come long after the watchdog tripped. The link is
also declared lost once, since the last good poll, it has answered no request for `count` x
`gap` s and failed one at least (a stalled host whose answers are waiting is not a lost link).
"""

from __future__ import annotations

import asyncio
import logging
import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from drives.errors import DriveError, DriveTimeoutError

if TYPE_CHECKING:
    from drives.link import ModbusLink

log = logging.getLogger(__name__)


def fit_loss_polls(
    count: int, *, given: bool, request_timeout: float, poll_interval: float, watchdogs: Sequence[float]
) -> int:
    """`count` (failed polls that declare the link lost), lowered so that `count` x (request_timeout
    + poll_interval) (s) stays below the shortest of `watchdogs` (COMM_LOSS_TIMEOUT s, armed ones
    only); 1 with a warning when a single lost request already trips them. Lowering a count the
    user `given` is a warning, the default's an info. No watchdog: `count` unchanged."""
    if not watchdogs:
        return count
    shortest = min(watchdogs)
    gap = request_timeout + poll_interval  # longest silence after a lost request
    if gap >= shortest:
        log.warning(
            "request timeout %.2f s + poll interval %.2f s is not below the drives' "
            "COMM_LOSS_TIMEOUT of %.1f s: a single lost request trips them",
            request_timeout,
            poll_interval,
            shortest,
        )
        return 1
    if count * gap < shortest:
        return count
    fit = max(1, math.ceil(shortest / gap) - 1)  # fit x gap < watchdog, but for rounding:
    while fit > 1 and fit * gap >= shortest:  # 0.3 s / 0.1 s is 3.0000000000000004 in floats
        fit -= 1
    (log.warning if given else log.info)(
        "link_loss_polls %d x (request timeout %.2f s + poll interval %.2f s) = %.2f s "
        "is not below the drives' COMM_LOSS_TIMEOUT of %.1f s: the link is declared "
        "lost after %d failed poll(s) instead",
        count,
        request_timeout,
        poll_interval,
        count * gap,
        shortest,
        fit,
    )
    return fit


class LinkSilence:
    """Calls `lost(error, how)` once the link has answered nothing for `budget` s since the last
    good poll (`good`) and failed a request at least; checked again every `recheck` s until then.
    The error names the drive and registers of the last request that failed (`link.failed`), as a
    loss declared by failed polls names its poll's."""

    def __init__(self, link: ModbusLink, lost: Callable[[DriveError, str], None], recheck: float):
        self.link, self.lost, self.recheck = link, lost, recheck
        self._timer: asyncio.TimerHandle | None = None
        self._since = (0.0, 0, 0)  # (loop s, link.requests, link.failures) at the last good poll

    def good(self, budget: float) -> None:
        """A good poll now: the silence counts from here, `budget` s at most."""
        self.cancel()
        loop = asyncio.get_running_loop()
        self._since = (loop.time(), self.link.requests, self.link.failures)
        self._timer = loop.call_later(budget, self._check)

    def cancel(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None

    def _check(self) -> None:
        t0, answered, failed = self._since
        loop = asyncio.get_running_loop()
        if self.link.requests == answered and self.link.failures > failed:
            self._timer = None
            n = self.link.failures - failed
            silent = f"no answer for {loop.time() - t0:.2f} s, {n} request(s) failed, the last this one"
            self.lost(DriveTimeoutError(silent, **self.link.failed), "since the last good poll")
        else:
            self._timer = loop.call_later(self.recheck, self._check)
