"""The stop command to a set of drives: stop words first, to every drive, then zero references."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Awaitable, Callable, Sequence
from typing import TYPE_CHECKING

from drives import registers as R
from drives.errors import DriveError, DriveTimeoutError

if TYPE_CHECKING:
    from drives.drive import Drive

log = logging.getLogger(__name__)


class StopSender:
    """The stops of one set of drives, each in a task of its own (delivered even if whoever
    asked is cancelled), one after another: a stop asked while one is under way goes out
    once that one has (their words never interleave on the link)."""

    def __init__(self, drives: Sequence[Drive]):
        self.drives = drives
        self._last: asyncio.Task[list[DriveError]] | None = None

    def send(self, *, emergency: bool = False) -> asyncio.Task[list[DriveError]]:
        """Start a stop now; the task's result: the delivery errors (`send_stop`)."""
        before = self._last
        self._last = asyncio.get_running_loop().create_task(self._after(before, emergency), name="drives-stop")
        return self._last

    async def _after(self, before: asyncio.Task[list[DriveError]] | None, emergency: bool) -> list[DriveError]:
        if before is not None and not before.done():
            await asyncio.wait([before])
        return await send_stop(self.drives, emergency=emergency)


async def send_stop(drives: Sequence[Drive], *, emergency: bool = False) -> list[DriveError]:
    """Stop words to every drive (OFF1 ramp stop, or OFF3 emergency stop), then
    zero references so that no later start jumps back to the old speed.

    Control words go out first, to all drives, before anything else (ahead of
    every request waiting for the link, the poll's and the run's, and none of
    theirs between the stop's own); a drive
    that does not take it does not keep the others from getting theirs: each
    gets one try first, and only then are the timed-out ones retried
    (`Drive.write_retries`), so one silent drive delays the other's stop word by
    one request timeout, not by all its retries.
    Returns the delivery errors (logged), one per drive that missed its stop word.
    """
    word = R.CW_EMERGENCY_STOP if emergency else R.CW_RAMP_STOP
    with contextlib.ExitStack() as links:
        for link in {id(d.link): d.link for d in drives}.values():
            links.enter_context(link.reserved())  # the stop's words back to back
        errors = await _to_each(drives, lambda d, retries: d.write_control(word, retries=retries, urgent=True))
        for err in errors:
            log.error("stop command not delivered: %s", err)
        for err in await _to_each(drives, lambda d, retries: d.write_reference(0, retries=retries, urgent=True)):
            log.warning("zero reference not delivered: %s", err)
    return errors


def took_it(drives: Sequence[Drive], errors: Sequence[DriveError]) -> list[str]:
    """'spin (id 1)', ... of the `drives` whose stop word went out: those no error of `send_stop`
    names."""
    missed = {err.drive for err in errors}
    return [f"{d.name} (id {d.device_id})" for d in drives if d.device_id not in missed]


async def _to_each(drives: Sequence[Drive], write: Callable[[Drive, int], Awaitable[None]]) -> list[DriveError]:
    """`write(drive, retries)` to every drive: one try each, then the retries of
    those that timed out. Returns the errors of the drives that missed it."""
    errors: dict[int, DriveError] = {}
    timed_out = []
    for d in drives:
        try:
            await write(d, 0)
        except DriveTimeoutError as err:
            timed_out.append(d)
            errors[id(d)] = err
        except Exception as err:  # noqa: BLE001 - whatever one drive's write raised, the next gets its word
            errors[id(d)] = _as_drive_error(d, err)
    for d in timed_out:
        if d.write_retries < 1:
            continue
        log.warning("%s drive (id %d): write timed out; retrying", d.name, d.device_id)
        try:
            await write(d, d.write_retries - 1)
            del errors[id(d)]
        except Exception as err:  # noqa: BLE001
            errors[id(d)] = _as_drive_error(d, err)
    return [errors[id(d)] for d in drives if id(d) in errors]


def _as_drive_error(d: Drive, err: Exception) -> DriveError:
    """`err` of a write to `d` as the DriveError the stop reports (an unexpected kind named)."""
    if isinstance(err, DriveError):
        return err
    wrapped = DriveError(f"{type(err).__name__}: {err}", drive=d.device_id, drive_name=d.name)
    wrapped.__cause__ = err
    return wrapped
