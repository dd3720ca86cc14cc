"""Writes the link gave up on: they may still reach their drive, after requests sent since.

On TCP the link drops a connection whose request it gave up on (no answer within its timeout,
its caller cancelled, the connection broken under it); the next request, a stop's word among
them, goes out on a new one. Nothing orders two connections: the old request, held in a slow
path or in a gateway's queue, can reach the drive after the stop, and a start's word (REF, the
run word CW 0x047F) starts it again; or, a stop's word given up, after the next start, and stops
the drive the operator just started. The dropped connection is reset (RST, SO_LINGER 0:
drives/connection.py): the host's TCP stops retransmitting the request at once (a normal close
goes on retransmitting it, minutes at worst) and a well-behaved server drops what it has not
read; bytes already in the path, or a request a gateway has taken, still get through. So:

- `LateWrites` (the link's `late`) records every write the link gave up on, a stop's (an urgent
  write: its stop word or zero reference) marked as one (`GivenUp.stop`), and takes it to reach
  its drive, if ever, within LATE_TIMEOUTS request timeouts of the last write given up while it
  was still open (`until`: a path slow enough to hold one request is taken to hold the others it
  held as long as writes keep being given up, a stop's among them). The bound is ours: the
  contract says nothing of requests a client gave up on. After the rig has closed the link nothing
  reads the drives: a write later than that is caught by the drive's comm-loss watchdog alone.
- A stop is not done until the drives have been read at rest (`at_rest`: not operation
  enabled, REF 0, ACT 0) by reads sent after the window of the start's writes given up (`until`;
  a stop's word arriving late stops a drive: nothing to wait for): `RigDrives.stop`'s wait
  (drives/stop_wait.py, the poll reading on); the rig's exit after its stop (`watch`), which
  does not wait out the ramps, until they are read `unstarted` (not operation enabled, REF 0). A drive
  read after the stop running or with a nonzero REF while such a write to it may still arrive
  gets the stop word again, said as a warning naming the drive, the register read and the
  write given up (`late_found`).
- A drive found off its run command (drives/state.off_command) while a write to it given up may
  still arrive: a stop's word whose register reads it back (not running, CW the stop word; REF 0)
  is named as the cause (`stopped_late`: the drive stopped on our own earlier stop word, or runs at
  REF 0 on its zero reference, with the time it was given up), in place of another client or the keypad; a start's is named beside them
  (`off_command_late`). Either way the poll stops both and records the failure: the drive is not
  started again.
RTU carries one exchange at a time, in order: a write given up there reaches the drive, if at
all, before the next request; nothing is recorded.
"""

from __future__ import annotations

import asyncio
import dataclasses
import logging
import time
from collections.abc import Awaitable, Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from drives.errors import DriveError, DriveOffCommand, DriveTimeoutError
from drives.limits import fmt_speed
from drives.poll_pace import read_again_by
from drives import registers as R
from drives.registers import register_name, registers_name
from rigunits import utc_iso

if TYPE_CHECKING:
    from drives.drive import Drive, DriveStatus

log = logging.getLogger(__name__)

#: request timeouts after the last write given up within which a write given up is taken to reach
#: its drive, if ever
LATE_TIMEOUTS = 2


@dataclass(frozen=True)
class GivenUp:
    """A write the link gave up on: device id, first address, words, monotonic s given up and by
    when it has reached its drive if it ever does, whether it is a stop's (`stop`: its stop word
    or zero reference), and the POSIX s it was given up (`wall`, for the operator)."""

    device_id: int
    address: int
    values: tuple[int, ...]
    at: float
    until: float
    stop: bool = False
    wall: float = 0.0

    def said(self) -> str:
        """'CW (0) = 0x047F' (the register(s) and the words written)."""
        n = len(self.values)
        where = register_name(self.address) if n == 1 else registers_name(self.address, n)
        return f"{where} = {' '.join(f'0x{v:04X}' for v in self.values)}"


def said_all(given: Iterable[GivenUp]) -> str:
    """'REF (1) = 0x0FA0, CW (0) = 0x047F': each write given up said once, in the order given up."""
    return ", ".join(dict.fromkeys(g.said() for g in given))


class LateWrites:
    """The writes a TCP link gave up on that may still reach their drive (`timeout`: the link's, s)."""

    def __init__(self, timeout: float):
        self.timeout = timeout
        self.window = LATE_TIMEOUTS * timeout
        self._given_up: list[GivenUp] = []

    def note(self, device_id: int, address: int, values: Sequence[int], *, stop: bool = False) -> None:
        """A write of `values` from `address` to `device_id` given up now (`stop`: a stop's)."""
        now = time.monotonic()
        until = now + self.window  # those still open too: the path that held them is still slow
        self._given_up = [dataclasses.replace(g, until=until) for g in self._given_up if g.until > now]
        self._given_up.append(GivenUp(device_id, address, tuple(values), now, until, stop, time.time()))

    def open(self, device_ids: Iterable[int], at: float | None = None) -> list[GivenUp]:
        """The writes to `device_ids`, a stop's too, that may still arrive at `at` (monotonic s; None: now)."""
        at = time.monotonic() if at is None else at
        ids = set(device_ids)
        return [g for g in self._given_up if g.device_id in ids and g.until > at]

    def starts(self, device_ids: Iterable[int], at: float | None = None) -> list[GivenUp]:
        """`open`'s writes that are not a stop's: those that can start or speed up a drive."""
        return [g for g in self.open(device_ids, at) if not g.stop]

    def until(self, device_ids: Iterable[int], at: float | None = None) -> float | None:
        """Monotonic s by when every write but a stop's to `device_ids` open at `at` has arrived if
        ever (a stop's arriving late stops a drive: nothing to wait for); None: none open."""
        return max((g.until for g in self.starts(device_ids, at)), default=None)


def unstarted(st: DriveStatus) -> bool:
    """Read not operation enabled, at REF 0: nothing a late start word set (ACT may still ramp down)."""
    return not st.running and st.reference_raw == 0


def at_rest(st: DriveStatus) -> bool:
    """Read not operation enabled, at REF 0 and ACT 0: nothing a late start word found to undo."""
    return st.stopped and unstarted(st)


def late_found(
    statuses: Sequence[DriveStatus], late: LateWrites, since: float, stop: str, *, open_at: float | None = None
) -> list[str]:
    """Warnings for the drives of `statuses` (read after `since`, monotonic s: the stop's end) running
    or at a nonzero REF while a write to them given up before the stop (`stop`: which) may still
    arrive (at the read's asking; `open_at`: at that monotonic s instead): one such write reached it
    after the stop, and the stop word is written again. A drive found so once they can no longer
    arrive, or before any stop, is not theirs to explain (the poll's own finding): none."""
    found = []
    for st in statuses:
        at = st.asked if open_at is None else open_at
        given = [g for g in late.starts([st.device_id], at=at) if g.at <= since]
        if not given or st.asked <= since or not (st.running or st.reference_raw != 0):
            continue
        what = "CW (0) operation enabled" if st.running else f"REF (1) {fmt_speed(st.reference)}"
        found.append(
            f"{st.name} drive (id {st.device_id}): register {what}, ACT {fmt_speed(st.actual)} after the {stop}: "
            f"a write the link gave up on ({said_all(given)}) reached it late; "
            "the stop word is written again"
        )
    return found


def _reads_back(st: DriveStatus, g: GivenUp) -> bool:
    """Whether `st` shows what the stop's write `g` set: its stop word in CW with the drive no
    longer running, or REF 0."""
    if g.address == R.CW:
        return not st.running and (st.control_word,) == g.values
    return g.address == R.REF and st.reference_raw == 0 and g.values == (R.to_word(0),)


def stopped_late(st: DriveStatus, late: LateWrites) -> str | None:
    """Why `st`'s drive, found off its run command, most likely is (drives/state.off_command's
    cause): a stop's write to it given up, open at the read and read back (`_reads_back`), reached it
    after the start: 'most likely our own stop word given up unanswered at <UTC> ... and the drive
    stopped on that earlier stop' when its stop word in CW is read back, else 'most likely our own
    stop's zero reference (REF) given up ... and the drive runs at REF 0' (still running, ramping
    down). None when there is none. Another client writing the same word reads the same: said as
    the less likely."""
    given = [g for g in late.open([st.device_id], at=st.asked) if g.stop and _reads_back(st, g)]
    if not given:
        return None
    first = given[0]
    if any(g.address == R.CW for g in given):
        what, then = "stop word", "the drive stopped on that earlier stop"
    else:
        what, then = "stop's zero reference (REF)", "the drive runs at REF 0 from that earlier stop"
    return (
        f"most likely our own {what} given up unanswered at {utc_iso(first.wall)} ({st.asked - first.at:.2f} s "
        f"before this read: {said_all(given)}) reached it late, after the start, and {then} "
        "(else another client wrote the same word)"
    )


def run_undone(st: DriveStatus, late: LateWrites, what: str) -> DriveOffCommand | None:
    """A drive read, while its start waits for `what` after the run word was taken, not running on a
    stop's word of ours read back, or at REF 0 on a stop's zero reference of ours read back
    (`stopped_late`): the start cannot succeed, it ends at once naming that word (register SW).
    None when no such word is read back."""
    cause = stopped_late(st, late)
    if cause is None:
        return None
    return DriveOffCommand(
        f"{what} not reached (status word 0x{st.status_word:04X}: {st.state}): {cause}",
        drive=st.device_id,
        drive_name=st.name,
        register=R.SW,
    )


def off_command_late(err: DriveOffCommand, statuses: Sequence[DriveStatus], late: LateWrites) -> DriveOffCommand:
    """`err` (a drive found off its command: drives/state.off_command) naming a start's write to
    that drive the link gave up on and still open at the read as the likely cause beside another
    client or its keypad: a late REF moves a running drive off its command as they do. `err` itself
    when none is open, or when a late stop's word was named as the cause already (`stopped_late`)."""
    st = next((s for s in statuses if s.device_id == err.drive), None)
    given = late.starts([st.device_id], at=st.asked) if st is not None else []
    if not given or (st is not None and stopped_late(st, late) is not None):
        return err
    return DriveOffCommand(
        f"{err.reason}; or a write the link gave up on ({said_all(given)}) reached it late",
        drive=err.drive,
        drive_name=err.drive_name,
        register=err.register,
    )


async def watch(
    drives: Sequence[Drive],
    late: LateWrites,
    stop: Callable[[], Awaitable[list[DriveError]]],
    said: str,
    interval: float,
) -> list[DriveError]:
    """After the rig's last stop (`said`: which), with no poll left: read `drives` every `interval` s
    until a read sent after every given-up write to them can have arrived shows them `unstarted`
    (not at rest: the exit does not wait out their ramps); one read running or at a nonzero REF
    meanwhile gets `stop()` again (warned). Read failures are logged; the watch ends with the
    window + two intervals + a request's timeout at most. Returns what the exit raises: the errors
    of a stop sent again, and a DriveTimeoutError if the drives were not read stopping by the end."""
    ids = [d.device_id for d in drives]
    until = late.until(ids)
    if until is None:
        return []
    start = since = time.monotonic()
    errors: list[DriveError] = []
    deadline = read_again_by(until, interval, late.timeout)
    log.warning("a write given up may still reach a drive: both are watched for %.2f s", until - since)
    while time.monotonic() < deadline:
        try:
            statuses = [await d.read_status(retries=0) for d in drives]
        except Exception as err:  # noqa: BLE001 - the watch goes on to its end whatever a read raised
            log.warning("drive status not read while watching for a late write: %s", err)
            statuses = []
        found = late_found(statuses, late, since, said, open_at=start)  # no poll's finding to fall back on
        for words in found:
            log.warning("%s", words)
        if found:
            errors += await stop()
            since = time.monotonic()
        elif statuses and all(unstarted(st) and st.asked > until for st in statuses):
            return errors
        await asyncio.sleep(interval)
    words = f"drives not read stopping once every write given up could have arrived (after the {said})"
    log.error("%s", words)
    return [*errors, DriveTimeoutError(words)]
