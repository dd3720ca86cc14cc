"""The stop command to a set of drives: stop words first, to every drive, then zero references.

Conventions:

- A stop writes its control word (OFF1 ramp stop, OFF3 emergency stop) to every drive,
  one try each, then the retries, then REF = 0 to every drive the same way.
- A write is tried again (`Drive.write_retries` more tries) after a passing failure (`passing`):
  a timeout, a Modbus exception that says "not now" (`PASSING_EXCEPTIONS`: 06 busy, 0A / 0B
  gateway), or a connection that broke under the request (DriveLinkDropped: a TCP connection
  reset or closed, an RTU line error; the retry goes out on a new connection). Writing a control
  word or a reference again is harmless. Any other error is not retried: a connect that failed
  (DriveConnectError: nothing answered at the address, at the cost of up to the request timeout +
  CONNECT_EXTRA_S; the next connect would most likely cost as much again), a request to a device
  id the link keeps unaddressed (drives/starve.py starves that drive's watchdog on purpose), except
  an emergency stop word (OFF3) of a `StopSender`'s stop: its `lifts` (the poll's Starver) let that
  word of one stop through to a starved drive, each try of it, and starve it again after.
- `StopSender` sends the stops of one set of drives one after another; their words never
  interleave on the link (`ModbusLink.reserved`, held from the moment a stop task runs).
- Every emergency stop word (OFF3) written to a drive is noted per link before it goes out
  (drives/emergency_sent.py: a stop asked soon after is the emergency stop too). A ramp stop over a
  bare link reads each drive's status word first (drives/read_first.py); a stop's kind and who took
  it are worded in drives/stop_said.py, how long the drives take to stop in drives/ramp_down.py.
- An emergency stop asked while a stop is under way takes it over: every control word that
  stop has still to write is OFF3, and the drives that took its OFF1 get OFF3 next, after the
  request on the link but before any retry not yet begun (the link's own retries of one call,
  `Drive.write_retries` - 1 at most, keep their word). A stop leaves its zero references to
  the stop asked after it, so the words of every stop asked go out before any zero reference.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import weakref
from collections.abc import Awaitable, Callable, Sequence
from typing import TYPE_CHECKING

from drives import registers as R
from drives.emergency_sent import emergency_sent
from drives.errors import DriveError, DriveExceptionResponse, DriveLinkDropped, DriveTimeoutError
from drives.local_control import DriveInLocalControl, said_local_all

if TYPE_CHECKING:
    from drives.drive import Drive

log = logging.getLogger(__name__)

#: Modbus exception codes retried like a timeout: 06 server device busy, 0A gateway path
#: unavailable, 0B gateway target device failed to respond.
PASSING_EXCEPTIONS = frozenset({0x06, 0x0A, 0x0B})

#: `write(drive, value, retries)`: one write of `value`, the link retrying its timeouts `retries` times.
_Write = Callable[["Drive", int, int], Awaitable[None]]

#: `quiet(err)`: whether a stop's delivery error is said already (logged at DEBUG, not ERROR)
Quiet = Callable[[DriveError], bool]


def loud(err: DriveError) -> bool:
    """Every delivery error said (ERROR): the `quiet` of a stop that keeps nothing back."""
    return False


#: `lift(drive)`: a context in which a request may go to `drive` though its watchdog is starved
Lift = Callable[["Drive"], contextlib.AbstractContextManager[None]]


class StopSender:
    """The stops of one set of drives, each in a task of its own (delivered even if whoever
    asked is cancelled), one after another: a stop asked while one is under way goes out
    once that one has (their words never interleave on the link). Stops are numbered in the
    order asked; an emergency stop turns every earlier stop still under way into one."""

    def __init__(self, drives: Sequence[Drive]):
        self.drives = drives
        self._last: asyncio.Task[list[DriveError]] | None = None
        self._asked = 0  # number of the last stop asked
        self._emergency = 0  # number of the last emergency stop asked (0: none)
        self._numbers: weakref.WeakKeyDictionary[asyncio.Task[list[DriveError]], int] = weakref.WeakKeyDictionary()
        # each stop's lift: its OFF3 word to a drive whose watchdog is starved (drives/starve.py)
        self.lifts: Callable[[], Lift] = lambda: _unlifted

    @property
    def asked(self) -> int:
        """Stops asked so far: a command given at one count is withdrawn once it changes."""
        return self._asked

    def send(self, *, emergency: bool = False, quiet: Quiet = loud) -> asyncio.Task[list[DriveError]]:
        """Start a stop now; the task's result: the delivery errors (`send_stop`; those `quiet`
        says are said already logged at DEBUG, not ERROR)."""
        before = self._last
        self._asked += 1
        if emergency:
            self._emergency = self._asked
        task = asyncio.get_running_loop().create_task(self._after(before, self._asked, quiet), name="drives-stop")
        self._last, self._numbers[task] = task, self._asked
        return task

    def emergency(self, task: asyncio.Task[list[DriveError]]) -> bool:
        """Whether the stop of `task` (from `send`) is the emergency stop (OFF3): its words are, or
        those it has still to write (an emergency stop asked after it took it over). The one place
        that knows which word a stop sent: its messages are worded from it (`stop_kind`)."""
        return self._word(self._numbers[task]) == R.CW_EMERGENCY_STOP

    def _word(self, n: int) -> int:
        """The control word of stop `n` now: OFF3 if it or any stop asked after it is an emergency stop."""
        return R.CW_EMERGENCY_STOP if self._emergency >= n else R.CW_RAMP_STOP

    async def _after(self, before: asyncio.Task[list[DriveError]] | None, n: int, quiet: Quiet) -> list[DriveError]:
        with _reserved(self.drives):  # no other request between the stop under way and this one
            if before is not None and not before.done():
                await asyncio.wait([before])
            return await _stop(
                self.drives, lambda: self._word(n), superseded=lambda: self._asked > n, lift=self.lifts(), quiet=quiet
            )


async def send_stop(drives: Sequence[Drive], *, emergency: bool = False) -> list[DriveError]:
    """Stop words to every drive (OFF1 ramp stop, or OFF3 emergency stop), then
    zero references so that no later start jumps back to the old speed.

    Control words go out first, to all drives, before anything else (ahead of
    every request waiting for the link, the poll's and the run's, and none of
    theirs between the stop's own); a drive
    that does not take it does not keep the others from getting theirs: each
    gets one try first, and only then are the failed ones retried (after a
    timeout, a passing exception answer or a broken connection, `Drive.write_retries`), so one
    silent drive delays the other's stop word by one request timeout (one connect's, request
    timeout + CONNECT_EXTRA_S, if nothing answers at its address: not retried), not by all its retries.
    Returns the delivery errors (logged), one per drive that missed its stop word.
    """
    word = R.CW_EMERGENCY_STOP if emergency else R.CW_RAMP_STOP
    return await _stop(drives, lambda: word, superseded=lambda: False)


async def _stop(
    drives: Sequence[Drive],
    word: Callable[[], int],
    superseded: Callable[[], bool],
    lift: Lift | None = None,
    quiet: Quiet = loud,
) -> list[DriveError]:
    """`send_stop` with the control word `word()` read before each write; the zero references
    end (left to the later stop) once `superseded()`; an OFF3 word goes out within `lift(drive)`;
    a delivery error `quiet` says is said already is logged at DEBUG: a retry's at once, the word's
    own only when read as a refusal in local control (a drive known held that refuses it in network
    control, busy or a gateway's answer, or whose status read fails, is an ERROR as always)."""
    with _reserved(drives):  # the stop's words back to back
        errors = await _to_each(drives, lambda d, cw, retries: _write_control(d, cw, retries, lift), word, quiet=quiet)
        zero = _to_each(
            drives, lambda d, ref, retries: d.write_reference(ref, retries=retries, urgent=True), lambda: 0, superseded
        )
        for err in await zero:
            log.warning("zero reference not delivered: %s", err)
    errors = await said_local_all(drives, errors, word(), superseded)  # once all went out; not held by a read
    for err in errors:  # DEBUG only once read as the keypad's refusal: a refusal for another reason is said
        said = isinstance(err, DriveInLocalControl) and quiet(err)
        log.log(logging.DEBUG if said else logging.ERROR, "stop command not delivered: %s", err)
    return errors


async def _write_control(d: Drive, cw: int, retries: int, lift: Lift | None) -> None:
    """A stop's control word `cw` to `d`; an emergency stop word is remembered before it goes out
    (a write that fails may still have reached the drive), and goes out within `lift(d)` (a drive
    whose watchdog is starved gets it all the same)."""
    if cw == R.CW_EMERGENCY_STOP:
        emergency_sent(d.link.url)
    with lift(d) if cw == R.CW_EMERGENCY_STOP and lift is not None else contextlib.nullcontext():
        await d.write_control(cw, retries=retries, urgent=True)


def _unlifted(d: Drive) -> contextlib.AbstractContextManager[None]:
    """No request is let through to a drive the link keeps unaddressed."""
    return contextlib.nullcontext()


def _reserved(drives: Sequence[Drive]) -> contextlib.ExitStack:
    """A context: the links of `drives` reserved for urgent requests (a stop's) while open."""
    links = contextlib.ExitStack()
    for link in {id(d.link): d.link for d in drives}.values():
        links.enter_context(link.reserved())
    return links


async def _to_each(
    drives: Sequence[Drive],
    write: _Write,
    wanted: Callable[[], int],
    superseded: Callable[[], bool] = lambda: False,
    quiet: Quiet = loud,
) -> list[DriveError]:
    """The value `wanted()` (read before each write) to every drive: one try each; then the
    drives that took an older value than the one wanted now (OFF1 once OFF3 is asked) get it,
    ahead of the retries of the drives whose try failed for a passing reason (`passing`),
    one drive's retries at a time (each said, at DEBUG if `quiet` says its failure is said
    already). Ends early once `superseded()`. Returns the errors of the drives that took no value."""
    w = _Writes(write, wanted, quiet)
    again: list[Drive] = []  # to be retried, in order
    for d in drives:
        if superseded():
            break
        if not await w.once(d) and passing(w.errors[id(d)]):
            again.append(d)
    while not superseded():
        stale = w.stale(drives)
        if stale:  # before anyone's retries
            for d in stale:
                if not await w.once(d) and passing(w.errors[id(d)]) and d not in again:
                    again.append(d)
        elif again:
            await w.retried(again.pop(0))
        else:
            break
    for d in w.stale(drives, tried=True):
        log.error(
            "%s drive (id %d) took %#06x, not %#06x: %s",
            d.name,
            d.device_id,
            w.took[id(d)],
            wanted(),
            w.errors.get(id(d)),
        )
    return [w.errors[id(d)] for d in drives if id(d) not in w.took and id(d) in w.errors]


class _Writes:
    """One value to each of a set of drives (`_to_each`): the value each took, the value last
    tried, and the error of each drive's last failed try."""

    def __init__(self, write: _Write, wanted: Callable[[], int], quiet: Quiet = loud):
        self.write, self.wanted, self.quiet = write, wanted, quiet
        self.took: dict[int, int] = {}  # id(drive) -> the value it took last
        self.tried: dict[int, int] = {}  # id(drive) -> the value tried last
        self.errors: dict[int, DriveError] = {}  # id(drive) -> the error of its last try, if it failed

    async def once(self, d: Drive, retries: int = 0) -> bool:
        """Write the value wanted now to `d` (the link retrying `retries` timeouts); whether it took it."""
        value = self.tried[id(d)] = self.wanted()
        try:
            await self.write(d, value, retries)
        except Exception as err:  # noqa: BLE001 - whatever one drive's write raised, the next gets its word
            self.errors[id(d)] = _as_drive_error(d, err)
            return False
        self.took[id(d)] = value
        self.errors.pop(id(d), None)
        return True

    async def retried(self, d: Drive) -> None:
        """Up to `d.write_retries` tries more, while they fail for a passing reason."""
        left = d.write_retries
        while left > 0:
            err = self.errors[id(d)]
            level = logging.DEBUG if self.quiet(err) else logging.WARNING
            log.log(level, "%s drive (id %d): %s; trying again", d.name, d.device_id, err.reason)
            before = d.link.retries
            if await self.once(d, retries=left - 1):
                return
            left -= 1 + d.link.retries - before  # the link's own retries (timeouts, broken connections) count
            if not passing(self.errors[id(d)]):
                return

    def stale(self, drives: Sequence[Drive], *, tried: bool = False) -> list[Drive]:
        """The drives that took a value other than the one wanted now, and have not been tried with
        it yet (`tried`: also those that have)."""
        value = self.wanted()
        return [
            d
            for d in drives
            if id(d) in self.took and self.took[id(d)] != value and (tried or self.tried[id(d)] != value)
        ]


def passing(err: DriveError) -> bool:
    """Whether `err` may pass on a second try: a timeout, a busy / gateway exception answer, or a
    connection broken under the request (the retry reconnects; a failed connect is not passing)."""
    if isinstance(err, DriveExceptionResponse):
        return err.exception_code in PASSING_EXCEPTIONS
    return isinstance(err, (DriveTimeoutError, DriveLinkDropped))


def _as_drive_error(d: Drive, err: Exception) -> DriveError:
    """`err` of a write to `d` as the DriveError the stop reports (an unexpected kind named)."""
    if isinstance(err, DriveError):
        return err
    wrapped = DriveError(f"{type(err).__name__}: {err}", drive=d.device_id, drive_name=d.name)
    wrapped.__cause__ = err
    return wrapped
