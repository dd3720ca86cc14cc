"""The last way a network master has to stop a drive that will not stop: starve its watchdog.

A drive's comm-loss watchdog (COMM_LOSS_TIMEOUT, register 104) trips fault 7510, whose reaction
is a ramp stop, once no valid request addressed to it came for that long. Every request the
drive answers feeds it, exception answers included (the simulator counts them; the contract
says "valid request"), so a drive that answers the stop's words with an exception, or takes
them and runs on, is kept running by the poll's own reads and resends. `Starver`, the poll's:

- `judge` (every poll with no speed commanded; reads after the first stop since the last
  command ended, `stop_ended`): a drive read operation enabled (SW RDY_REF) with a nonzero
  REF or ACT is defiant from that read on, and starved once still read so `bound` s later:
  two poll intervals (the stop sent again at least once more, and read after it), plus, at
  REF = 0, its own ramp from the speed read (DECEL_TIME x |ACT| / SPEED_SCALE: a drive that
  follows a zero REF in operation is stopping, merely slowly); a poll in between that reads it
  stopping or stopped forgives it. Later stops (in flight, or ended after the read: an operator
  pressing stop again and again) change nothing: it has missed or ignored the ones before.
  A drive that took a stop word leaves operation enabled at once (OFF1/OFF3 ACTIVE, the
  contract's state machine and the simulator's): a ramp stop is never taken for defiance.
  A drive enabled at REF 0 and standstill is not starved (it does not turn; the stop goes on).
- Starving: its id goes into the link's `unaddressed` (no read, no write, no stop's word) for
  COMM_LOSS_TIMEOUT + `MARGIN_S` + two poll intervals after the decision; the other drive is
  polled on (the poll reuses the starved drive's last status). With COMM_LOSS_TIMEOUT 0 or not
  known, it is not starved: the finding says at once that nothing over the network stops it.
- The first emergency stop (OFF3: an abort's, an operator's) asked while it is starved is not kept
  from it: its emergency ramp is ten times faster than the ramp stop its watchdog's fault 7510
  brings. `lifting` (the StopSender's `lifts`, one per stop) lets that stop's OFF3 word through to
  it, each try of it. A try that failed (refused, unanswered) starves it again, its clock started
  again (that request may have fed its watchdog). A word it took (answered) puts it in its
  emergency ramp phase: it is addressed and read by the poll, so its standstill is seen (`state`,
  a stop's wait), for as long as each read shows it in its emergency ramp (SW OFF_3_STA 0), no
  faster than the read before, and at a speed it can still lose in that ramp by `ramp_end`: the
  word taken + that ramp's time from the speed it was starved at (DECEL_TIME / 10 x |ACT| /
  SPEED_SCALE) + two polls + a request's timeout. What is judged is its speed, against that
  ramp's profile, as of when the poll that read it began (`outcome`'s `asked`), not the wall time
  its answer was handled: a busy host's late poll or late answer shows the speed of an earlier
  moment, which a drive slowing in that ramp has always lost in time; a drive in OFF_3_STA 0 that
  does not slow fails that bound by `ramp_end` at the latest. Only reads after the word was
  taken count: the poll's stand-in for a starved drive (its last status, read before the word)
  is not judged. The reads feed its watchdog only while the OFF3, ten times faster than the
  watchdog's stop, is stopping it. Read at standstill (or tripped) that is its outcome; read
  otherwise (it took the word and runs on, not in its emergency ramp, or slower than that ramp)
  it is starved again from that read, and its watchdog trips it all the same. Later emergency
  stops (pressed again and again) are not let through: they would keep its watchdog fed. Ramp
  stop words (OFF1) and zero references are never let through to a starved drive (one read in
  its emergency ramp is addressed: that stop's zero reference reaches it).
- `ended` / `outcome`: then it is addressed again and the next poll's read of it is the
  finding: tripped (7510) and slowing, or still running: nothing over the network can stop
  it, the rig's emergency stop must. A drive is starved once until the next speed command.
  A rig closing meanwhile waits (`due`) for the poll to read it again before the poll ends, so
  no run ends without the outcome; cancelled, it closes unread (its exit's stop skips it).
A drive in local control (SW REMOTE = 0) is starved too, said in the finding: the contract
does not say whether the keypad disarms the watchdog (the simulator's does).
"""

from __future__ import annotations

import contextlib
import enum
import logging
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

from drives.drive import Drive, DriveStatus
from drives.errors import DriveError
from drives.findings import defies_stop, emergency_outcome, starved_outcome
from drives.limits import fmt_speed
from drives.link import ModbusLink
from drives.ramp_down import ramp_down_time
from drives.stop import Lift

log = logging.getLogger(__name__)

#: s added to COMM_LOSS_TIMEOUT (and two poll intervals) before a starved drive is read again:
#: the drive's watchdog resolution and a busy host's scheduling
MARGIN_S = 0.5


class Phase(enum.Enum):
    DEFIANT = "defiant"  # read running after the stop: starved if still so at `at`
    STARVED = "starved"  # not addressed until `at`
    READ_AGAIN = "read again"  # addressed again: the next read of it is the outcome
    EMERGENCY = "emergency ramp"  # took the OFF3 let through: read while it slows in its emergency ramp
    DONE = "done"  # starved, or found unstoppable, since the last speed command: not again


_UNREAD = (Phase.STARVED, Phase.READ_AGAIN, Phase.EMERGENCY)  # starving, its outcome not read yet


@dataclass
class _Drive:
    phase: Phase
    at: float  # monotonic s: when a defiant drive is starved, or a starved one read again
    first: DriveStatus  # the read that found it defiant
    last: DriveStatus  # the latest read (while starved: the one before)
    began: float = 0.0  # monotonic s the starving began (or its clock started again: `lifting`)
    lifted: object = None  # the stop whose emergency stop word was let through to it, if any
    why: str = ""  # why the link does not address it (ModbusLink.unaddressed)
    ramp_end: float = 0.0  # monotonic s: in its emergency ramp, its speed read lost by then or starved again


class Starver:
    """The drives of one poll whose comm-loss watchdog is starved, or may have to be."""

    def __init__(self, link: ModbusLink, drives: Sequence[Drive], poll_interval: float):
        self.link, self.drives, self.poll_interval = link, drives, poll_interval
        self._of: dict[int, _Drive] = {}  # device id -> its starving, if any
        self._stopped_at: float | None = None  # monotonic s the first stop since the last command ended

    def reset(self) -> None:
        """A speed was commanded: drives not starved now are judged afresh, after its next stop."""
        self._of = {k: v for k, v in self._of.items() if v.phase is Phase.STARVED}
        self._stopped_at = None

    def stop_ended(self) -> None:
        """A stop ended (taken or not): the first since the last speed command starts the clock
        of `judge` (reads after it are judged)."""
        if self._stopped_at is None:
            self._stopped_at = time.monotonic()

    def starved(self, d: Drive) -> DriveStatus | None:
        """`d`'s last status while it is not addressed (the poll shows it), else None."""
        s = self._of.get(d.device_id)
        return s.last if s is not None and s.phase is Phase.STARVED else None

    def judge(self, statuses: Sequence[DriveStatus], *, took: bool) -> list[DriveError]:
        """Statuses of a poll with no speed commanded (`took`: the last stop both drives took, else
        one is owed): the findings of the drives starved now (or found unstoppable: no watchdog),
        logged as errors. Reads before the first stop since the command ended are not judged;
        a drive read stopping or stopped is forgiven; whether a stop is in flight or ended after
        the read does not matter: stops pressed again and again must not keep its watchdog fed."""
        found: list[DriveError] = []
        for d, st in zip(self.drives, statuses):
            s = self._of.get(d.device_id)
            if s is not None and s.phase is not Phase.DEFIANT:
                continue
            if not _moving(st):
                self._of.pop(d.device_id, None)
            elif self._stopped_at is None or st.time <= self._stopped_at:
                continue
            elif s is None:
                self._of[d.device_id] = _Drive(Phase.DEFIANT, st.time + self._bound(d, st), st, st)
            elif st.time >= s.at:
                found.append(self._starve(d, s, st, took))
        return found

    def _bound(self, d: Drive, st: DriveStatus) -> float:
        """s a defiant drive is given: two poll intervals, plus its ramp to zero at REF = 0."""
        ramp = ramp_down_time(d.params, st.actual) if d.params is not None and st.reference_raw == 0 else 0.0
        return 2 * self.poll_interval + ramp

    def _starve(self, d: Drive, s: _Drive, st: DriveStatus, took: bool) -> DriveError:
        err = defies_stop(st, d.params, since=st.time - s.first.time, took=took)
        s.last, s.began, timeout = st, time.monotonic(), d.params.comm_loss_timeout if d.params is not None else 0.0
        if timeout:
            s.why = f"its comm-loss watchdog is being starved ({err.reason})"
            self._starve_from(d, s, s.began)
        else:
            s.phase = Phase.DONE
        log.error("%s", err)
        return err

    def lifting(self) -> Lift:
        """One stop's `lift(d)`: a context in which its emergency stop word goes to `d` though its
        watchdog is starved, if no earlier stop's went to it in this starving; after it, `d` is
        starved again (unless its starving ended meanwhile), its clock started again."""
        stop = object()
        return lambda d: self._lifted(d, stop)

    @contextlib.contextmanager
    def _lifted(self, d: Drive, stop: object) -> Iterator[None]:
        s = self._of.get(d.device_id)
        if s is None or s.phase is not Phase.STARVED or s.lifted not in (None, stop):
            yield
            return
        s.lifted = stop
        if self.link.unaddressed.pop(d.device_id, None) is None:
            yield
            return
        log.warning("%s drive (id %d): its watchdog starved, the emergency stop goes to it", d.name, d.device_id)
        try:
            yield
        except BaseException:
            if s.phase is Phase.STARVED:  # that request may have fed it: starved again from now
                self._starve_from(d, s, time.monotonic())
            raise
        if s.phase is Phase.STARVED:  # taken: read while it slows in its emergency ramp
            ramp = _emergency_ramp(d, s.last.actual) + 2 * self.poll_interval + self.link.timeout
            s.phase, s.began = Phase.EMERGENCY, time.monotonic()
            s.at, s.ramp_end = s.began + self._length(d), s.began + ramp

    def _length(self, d: Drive) -> float:
        """s a starved drive is not addressed: COMM_LOSS_TIMEOUT + MARGIN_S + two polls."""
        return (d.params.comm_loss_timeout if d.params is not None else 0.0) + MARGIN_S + 2 * self.poll_interval

    def _starve_from(self, d: Drive, s: _Drive, began: float) -> None:
        """`d` is not addressed from `began` (monotonic s: its watchdog's last request) on."""
        s.phase, s.began, s.at = Phase.STARVED, began, began + self._length(d)
        self.link.unaddressed[d.device_id] = s.why

    def ended(self) -> None:
        """Starved drives whose time is up are addressed again (`outcome` reads them)."""
        now = time.monotonic()
        for d in self.drives:
            s = self._of.get(d.device_id)
            if s is not None and s.phase is Phase.STARVED and now >= s.at:
                self.link.unaddressed.pop(d.device_id, None)
                s.phase = Phase.READ_AGAIN

    def due(self) -> float | None:
        """Monotonic s the last drive being starved is addressed again (or now, one addressed
        again and not read yet); None if none is: the rig's exit waits for its outcome."""
        now = time.monotonic()
        due = [now if s.phase is Phase.READ_AGAIN else s.at for s in self._of.values() if s.phase in _UNREAD]
        return max(due) if due else None

    def outcome(self, statuses: Sequence[DriveStatus], *, asked: float) -> list[DriveError]:
        """The findings of the drives read again in `statuses`, or read at standstill (or tripped)
        in the emergency ramp of the OFF3 let through (logged as errors); one read there not slowing
        in it is starved again. `asked`: monotonic s the poll that read them began (its requests
        went out after it). A status read before that OFF3 was taken (the poll's stand-in for a
        drive starved then, `starved`) is not judged."""
        found: list[DriveError] = []
        for d, st in zip(self.drives, statuses):
            s = self._of.get(st.device_id)
            if s is None or s.phase not in (Phase.READ_AGAIN, Phase.EMERGENCY):
                continue
            if s.phase is Phase.READ_AGAIN:
                err = starved_outcome(st, s.last, st.time - s.began)
            elif st.time <= s.began:  # read before it took the OFF3: tells nothing of its emergency ramp
                continue
            elif st.stopped or st.tripped:
                err = emergency_outcome(st, s.last, st.time - s.began)
            else:
                self._ramping(d, s, st, asked)
                continue
            s.phase = Phase.DONE
            log.error("%s", err)
            found.append(err)
        return found

    def _ramping(self, d: Drive, s: _Drive, st: DriveStatus, asked: float) -> None:
        """`d` read turning after it took the OFF3 let through: read on while `st` shows it in its
        emergency ramp, no faster than before, at a speed that ramp still takes to zero by `ramp_end`
        counted from `asked` (the read's request went out after it: a late answer, or a busy host
        handling it late, shows the speed of an earlier moment); else starved again from this read."""
        left = _emergency_ramp(d, st.actual)
        if st.emergency_ramp and abs(st.actual_raw) <= abs(s.last.actual_raw) and asked + left <= s.ramp_end:
            s.last, s.at = st, st.time + self._length(d)
            return
        log.warning(
            "%s drive (id %d): read %s at ACT %s after it took the emergency stop, not slowing in its "
            "emergency ramp: its watchdog is starved again",
            d.name,
            d.device_id,
            st.state,
            fmt_speed(st.actual),
        )
        s.last = st
        self._starve_from(d, s, st.time)


def _emergency_ramp(d: Drive, speed: float) -> float:
    """s `d`'s emergency ramp (OFF3) takes from `speed` (rad/s) to zero; 0 without its parameters."""
    return ramp_down_time(d.params, speed, emergency=True) if d.params is not None else 0.0


def _moving(st: DriveStatus) -> bool:
    """Whether `st` reads its drive defying a stop: operation enabled with a nonzero REF or ACT."""
    return st.running and bool(st.reference_raw or st.actual_raw)
