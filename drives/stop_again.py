"""A stop word some drive did not take for a reason that may pass, sent again until it is taken.

`RigDrives.stop` (with its wait for standstill) sends its stop again to both drives while every
drive that did not take it failed for a reason that may pass: no answer (a link that went silent
under the ramp), a connection broken under the request or a connect that failed (a cable pulled
and put back, a switch restarted), a busy or gateway exception answer (`may_pass`). A pause of
`PAUSE_S` wall s between two sends; the tries end once both drives took the word or the time to
send it again is out (`resend_deadline`): the stop's wait for standstill ([drives] stop_timeout_s
+ 5 s for a run), or sooner when every drive has its comm-loss watchdog and only silence kept the
word from them: their watchdog + `WATCHDOG_MARGIN_S` after the first failure, by when a drive no
request reaches has stopped on its own (fault 7510), which no word sent again changes. A refusal
that will not pass (exception 03, a drive the link keeps unaddressed) is not sent again: the stop
raises it at once, as before. Sending a stop word again is harmless (the same word; an emergency
stop asked meanwhile makes it OFF3, drives/owed.py). Without this a link silent for 0.45 s (three
tries of 0.15 s) under a run's closing stop left the stop "not confirmed" although the link came
back a moment later with both drives at standstill. What each send says of a drive held at its keypad
is paced by the poll's holds (drives/local_hold.py; RigStop._sent_again), not an ERROR per send.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Awaitable, Callable, Sequence

from typing import TYPE_CHECKING

from drives.errors import DriveConnectError, DriveError, DriveExceptionResponse
from drives.stop import passing

if TYPE_CHECKING:
    from drives.drive import Drive

#: wall s between two sends of a stop word not taken (a connect refused fails at once)
PAUSE_S = 0.1
#: wall s past the drives' comm-loss watchdog that a word kept from them by silence is sent again
WATCHDOG_MARGIN_S = 1.0


def may_pass(err: DriveError) -> bool:
    """Whether a drive's stop delivery error may pass if the word is sent again a moment later:
    a passing failure (drives/stop.py `passing`) or a connect that failed."""
    return passing(err) or isinstance(err, DriveConnectError)


def resend_deadline(drives: Sequence[Drive], errors: Sequence[DriveError], wait_end: float) -> float:
    """Monotonic s until which a stop word not taken (`errors`, just now) is sent again: `wait_end`
    (the stop's wait), or sooner, the drives' longest comm-loss watchdog + WATCHDOG_MARGIN_S from
    now, when every drive has one (read on entry) and no drive answered (an exception answer feeds
    a drive's watchdog: it runs on until a word reaches it)."""
    dogs = [d.params.comm_loss_timeout if d.params is not None else 0.0 for d in drives]
    if not all(dogs) or any(isinstance(e, DriveExceptionResponse) for e in errors):
        return wait_end
    return min(wait_end, time.monotonic() + max(dogs) + WATCHDOG_MARGIN_S)


async def send_until_taken(
    send: Callable[[], Awaitable[list[DriveError]]], errors: list[DriveError], drives: Sequence[Drive], wait_end: float
) -> tuple[list[DriveError], str]:
    """`send` the stop to `drives` again (its result: their delivery errors) while `errors` all `may_pass`
    and `resend_deadline` is not reached: (the last send's errors, what the sends again did:
    '' when there was none, else 'sent again 4 times after spin drive (id 1), register CW (0): no
    answer ...: taken by both', or '...: not taken', the first error then saying it too)."""
    first, again, deadline = errors, 0, resend_deadline(drives, errors, wait_end)
    while errors and all(may_pass(e) for e in errors) and time.monotonic() + PAUSE_S < deadline:
        await asyncio.sleep(PAUSE_S)
        errors = await send()
        again += 1
    if not again:
        return errors, ""
    times = f"{again} time{'s' if again > 1 else ''}"
    if errors:  # what the stop raises says it too
        errors[0].args = (f"{errors[0].args[0]} (the stop word sent again {times}, not taken)",)
    return errors, f"sent again {times} after {first[0]}: {'not taken' if errors else 'taken by both'}"
