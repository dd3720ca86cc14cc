"""How many failed polls in a row declare the drive link lost, fitted under the drives' watchdog.

A drive trips (fault 7510) after COMM_LOSS_TIMEOUT s without a valid request. After a lost
request the longest silence is one request timeout plus one poll interval (`gap`); the link
must be declared lost (and the sweep's interlock act) before the watchdog trips the drives,
so `count` x `gap` is kept below the shortest watchdog.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence

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
