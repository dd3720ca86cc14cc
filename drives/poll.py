"""The poll of both drives: heartbeat, published state, link health, trip interlock.

One task (`DrivePoll.run`) reads both drives every `poll_interval` s at a steady pace. It is the
heartbeat the drives' comm-loss watchdog needs, the source of `state`, and the interlock:
- A drive that trips, or (once a poll found both at `command`, or read them after the start
  confirmed both: `started`) one found no longer running, in local control or at another
  reference (another client, the drive's keypad: DriveOffCommand), has both drives ramped to
  zero before it is recorded in `failure` (the owner raises it); so does a poll that fails on
  a bug (not left turning unwatched: the poll's reads keep their watchdog fed); such a poll
  also sends a stop that is owed again (it cannot find the drives running to do so).
- A poll's read gives way to a stop on TCP (drives/link.py): that poll is skipped, not failed.
- A new start judges the drives it reads as a poll does (`check_following`), and refuses what the
  poll found (`failure`, or `stopping_for` while its stop goes out): no start undoes that stop.
- A failed poll is counted (`state.poll_failures`, logged); the link is declared lost only after
  `link_loss_polls` consecutive failures (an isolated lost frame on a noisy RS-485 line is
  tolerated), or once it has answered nothing (and failed) for link_loss_polls x (poll_interval +
  timeout) s since the last good poll, whichever comes first (drives/heartbeat.py: other requests,
  a stop's tries, hold the poll's). `fit_heartbeat` keeps that time below COMM_LOSS_TIMEOUT.
- While the link is down the poll keeps reconnecting; once it is back, both drives are verified
  against `command` before anything goes on: drives found tripped, off their reference or in
  local control are stopped and the loss is recorded.
- What each poll checks in the statuses it read (a trip, the drives off the command, a stop owed
  or held, a late word, a drive running on through the stop) is drives/poll_checks.py's.
- A poll task that dies on an exception outside its polls (a bug in its pacing, in its own
  handling of a failed poll) leaves nobody watching the drives: both get the stop (best effort),
  then it is `crashed` (a DriveError naming it, chained to it; also the failure), never
  acknowledged; the waits on the poll are woken and raise it, and the task ends on the exception.
"""

from __future__ import annotations

import asyncio
import dataclasses
import logging
import time
from collections.abc import Sequence

from drives.drive import Drive, DriveStatus
from drives.errors import DriveError, DriveFaultError, DriveGaveWay
from drives.findings import reconnect_problem
from drives.heartbeat import LinkSilence, fit_loss_polls
from drives.link import ModbusLink
from drives.local_hold import LocalHolds
from drives.owed import OwedStops
from drives.poll_checks import PollChecks
from drives.poll_pace import PollPace
from drives.starve import Starver
from drives.state import RigDriveState
from drives.stop import Quiet, StopSender, loud

log = logging.getLogger(__name__)


class DrivePoll(PollChecks):
    """Polls the spin and orbit drives on one link; owned by `RigDrives`.

    poll_interval : s between polls of both drives.
    link_loss_polls : consecutive failed polls that declare the link lost; `loss_polls_given` (set
        by the user, not the default) makes lowering it in `fit_heartbeat` a warning, not an info.
    Shared with the owner:
    state : the latest RigDriveState; `tick` is set (and replaced) on every publish.
    command : raw REFs (spin, orbit) while running, else None; the owner sets it (`commanded`) and
        clears it with its stops (`send_stop`); the poll once its stop is sent, as it records the failure.
    owed : a stop some drive did not take (True: an emergency stop), None if none.
    failure : what the poll found (trip, failed verification after a link loss, a drive running
        while a stop is owed, a poll that raised), kept until `acknowledge()`; `stopping_for`:
        what its stop under way is for, before that.
    crashed : the poll task ended on an exception (nobody watches the drives): a DriveError naming
        it, never acknowledged; `alive()` raises it.
    """

    def __init__(
        self,
        link: ModbusLink,
        drives: tuple[Drive, Drive],
        *,
        poll_interval: float,
        link_loss_polls: int,
        loss_polls_given: bool,
        stops: StopSender | None = None,
    ):
        self.link = link
        self.drives = drives
        self.poll_interval = poll_interval
        self.pace = PollPace(poll_interval)
        self.link_loss_polls = link_loss_polls
        self._loss_polls_given = loss_polls_given
        self.state = RigDriveState(None, None, link_ok=False)
        self.tick = asyncio.Event()
        self.command: tuple[int, int] | None = None
        self.following = False  # a poll found both drives running at `command` since it was given
        self._started_at: float | None = None  # monotonic s the start confirmed both running at `command`
        self.failure: DriveError | None = None
        self.crashed: DriveError | None = None
        self.stopping_for: DriveError | None = None  # what the poll's stop under way is for, not yet a failure
        self._trip_handled = False
        self._ack_time = 0.0  # polls read before this are stale for trip handling
        self._link_lost_at: float | None = None  # monotonic s
        self.starver = Starver(link, drives, poll_interval)  # drives not addressed: their watchdog starved
        self._owed = OwedStops(stops or StopSender(drives), self.starver)  # the owner's: never interleaved
        self.holds = LocalHolds()  # drives refusing the stop sent again in local control: said at a pace
        self._silence = LinkSilence(link, self._link_down, recheck=poll_interval)  # armed while link_ok

    def alive(self) -> None:
        """Raise `crashed` if the poll task has died: no wait on its ticks may go on."""
        if self.crashed is not None:
            raise self.crashed

    def acknowledge(self) -> None:
        """Forget the recorded failure; trips read before now are not handled again."""
        self.failure = None
        self._trip_handled = False
        self._ack_time = time.monotonic()

    def commanded(self, refs: tuple[int, int]) -> None:
        """Both drives are being run at raw REFs `refs` (spin, orbit): no stop is owed any more."""
        self._owed.commanded()
        self.following, self._started_at = False, None
        self.starver.reset()
        self.command = refs

    def started(self) -> None:
        """The start has read both drives running at `command` (REF written, REMOTE accepted): a
        poll that reads them after now finds them off it only if someone else moved them."""
        self._started_at = time.monotonic()

    def emergency_found(self) -> None:
        """A drive read in its emergency ramp: every stop is one until a speed is commanded (drives/owed.py)."""
        self._owed.emergency_found()

    def send_stop(self, *, emergency: bool = False, quiet: Quiet = loud) -> asyncio.Task[list[DriveError]]:
        """Clear `command` (the owner's stop) and send the stop (drives/owed.py: owed until
        delivered to both); its task's result: the delivery errors (`quiet`: those said already)."""
        self.command = None
        return self._owed.send(emergency, quiet)

    def known_trips(self) -> frozenset[int]:
        """Device ids of the drives known tripped now: the latest poll's, and the recorded fault's."""
        st, err = self.state, self.failure
        known = {s.device_id for s in (st.spin, st.orbit) if s is not None and s.tripped}
        if isinstance(err, DriveFaultError) and err.fault_code and err.drive is not None:
            known.add(err.drive)
        return frozenset(known)

    def fit_heartbeat(self) -> None:
        """Lower `link_loss_polls` (and warn) when the drives' watchdog would trip
        before a link loss is declared (drives/heartbeat.py)."""
        watchdogs = [d.params.comm_loss_timeout for d in self.drives if d.params and d.params.comm_loss_timeout]
        self.link_loss_polls = fit_loss_polls(
            self.link_loss_polls,
            given=self._loss_polls_given,
            request_timeout=self.link.timeout,
            poll_interval=self.poll_interval,
            watchdogs=watchdogs,
        )

    def publish(self, statuses: Sequence[DriveStatus] | None, *, link_ok: bool, link_error: str | None = None) -> None:
        """A new `state` from `statuses` (None: keep the last drive statuses); wakes `tick`."""
        old = self.state
        spin, orbit = statuses if statuses else (old.spin, old.orbit)
        self.state = RigDriveState(
            spin=spin,
            orbit=orbit,
            link_ok=link_ok,
            link_error=link_error,
            link_losses=old.link_losses + (old.link_ok and not link_ok),
            polls=old.polls + 1,
            poll_failures=old.poll_failures + (not link_ok),
            failed_in_row=old.failed_in_row + 1 if not link_ok else 0,
            time=time.monotonic(),
        )
        if link_ok:  # the time bound of a declared loss counts from here
            self._silence.good(self.link_loss_polls * (self.poll_interval + self.link.timeout))
        else:
            self._silence.cancel()
        tick, self.tick = self.tick, asyncio.Event()
        tick.set()

    async def run(self) -> None:
        """Poll until cancelled, every `poll_interval` s (a late poll is not made up), and
        when `pace.ask`ed. A poll that fails on a bug is logged with its traceback once, not
        at every poll while it keeps failing."""
        failing = False
        try:
            while True:
                await self.pace.next_poll()
                try:
                    await self._poll_once()
                    failing = False
                except asyncio.CancelledError:
                    raise
                except Exception as err:  # a bug must not end the heartbeat, nor leave the drives turning unwatched
                    stop = self.command is not None or (self.owed is not None and not self._owed.sending)
                    if not failing or stop:
                        log.exception("drive poll failed" + ("; ramping both drives to zero" if stop else ""))
                    failing = True
                    if stop:  # what it can no longer judge is stopped, as after a trip; a stop owed is sent again
                        try:
                            await asyncio.shield(self._owed.send(bool(self.owed)))
                        except Exception:  # the stop's own failure must not end the heartbeat either
                            log.exception("drive poll: the stop after its failure failed")
                        self.command = None
                    self.fail(DriveError(f"poll failed: {err!r}"))
        except Exception as err:
            await self._crash(err)
            raise
        finally:
            self._silence.cancel()  # no loss declared once the poll has ended

    async def _crash(self, err: Exception) -> None:
        """The poll task ends on `err`: both drives get the stop (best effort; OFF3 if one is owed;
        a start meanwhile refused: `stopping_for`), then `crashed` is recorded (and the failure)
        and the waits are woken, also if the task is cancelled meanwhile."""
        crash = DriveError(f"the drives' poll crashed ({err!r}): nobody watches the drives; the stop sent to both")
        crash.__cause__ = err
        self.stopping_for = crash
        log.error("%s", crash, exc_info=err)
        try:
            await asyncio.shield(self._owed.send(bool(self.owed)))
        except Exception:
            log.exception("drive poll: the stop after its crash failed")
        finally:
            self.stopping_for, self.crashed, self.command = None, crash, None  # no await between: the waits see all
            self.fail(crash)
            tick, self.tick = self.tick, asyncio.Event()
            tick.set()

    async def read_now(self, ids: frozenset[int]) -> RigDriveState:
        """`state` with the drives of device `ids` read now, one request each, no retry (a drive
        whose watchdog is starved: its last status); its `time` that of the earliest read. For a
        wait on drives that answer while the poll fails on another (drives/stop_wait.py); a read
        that fails raises its DriveError."""
        read = {d.device_id: await self._read(d, retries=0) for d in self.drives if d.device_id in ids}
        old = self.state
        spin, orbit = (read.get(d.device_id, s) for d, s in zip(self.drives, (old.spin, old.orbit)))
        return dataclasses.replace(old, spin=spin, orbit=orbit, time=min(s.time for s in read.values()))

    async def _read(self, d: Drive, *, retries: int, gives_way: bool = False) -> DriveStatus:
        """`d`'s status (`Drive.read_status`), or while its watchdog is starved its last one."""
        return self.starver.starved(d) or await d.read_status(retries=retries, gives_way=gives_way)

    async def _poll_once(self) -> None:
        self.starver.ended()  # a drive starved long enough is read again
        was_ok, asked = self.state.link_ok, time.monotonic()  # the reads' requests go out after `asked`
        try:
            if was_ok:  # no retry: failed polls in a row bound the time to a declared loss
                statuses = [await self._read(d, retries=0, gives_way=True) for d in self.drives]
            else:
                statuses = await self._verify_after_reconnect()
        except DriveGaveWay:  # a stop took the link: no poll this time, and no failure
            log.debug("drive poll given up for a stop")
            return
        except DriveError as err:
            self._poll_failed(err)
            return
        if was_ok and not self.state.link_ok:  # declared lost meanwhile (LinkSilence): the next poll verifies
            return
        self.publish(statuses, link_ok=True)
        for found in self.starver.outcome(statuses, asked=asked):  # first: one starved again gets no stop sent again
            self.fail(found)
        await self._check_trips(statuses)
        await self.check_following(statuses)
        await self._check_owed(statuses)

    def _poll_failed(self, err: DriveError) -> None:
        """A poll without valid answers: counted; the link is declared lost after `link_loss_polls`
        in a row. Isolated failures keep `state` (statuses, time, `polls`): no old reading is new."""
        old = self.state
        in_row = old.failed_in_row + 1
        if not old.link_ok or in_row >= self.link_loss_polls:
            self._link_down(err, f"{in_row} failed polls in a row")
            return
        log.warning("drive poll failed (%d in a row; link declared lost at %d): %s", in_row, self.link_loss_polls, err)
        self.state = dataclasses.replace(
            old, poll_failures=old.poll_failures + 1, failed_in_row=in_row, link_error=str(err)
        )

    def _link_down(self, err: DriveError, how: str) -> None:
        """Declare the link lost (`how`: after what), or (lost already) count the failed poll."""
        if self.state.link_ok:
            self._link_lost_at = time.monotonic()
            watchdogs = [d.params.comm_loss_timeout for d in self.drives if d.params]
            log.error(
                "drive link lost (%s): %s; a drive no request reaches stops on its comm-loss watchdog after "
                "%s s (one still answering, with exceptions, does not); reconnecting",
                how,
                err,
                max(watchdogs) if watchdogs else "?",
            )
        self.publish(None, link_ok=False, link_error=str(err))

    async def _verify_after_reconnect(self) -> list[DriveStatus]:
        """Link is back: re-read parameters and check both drives against the command, or, with
        none, against the stop owed: drives found tripped, off their reference, or running while
        a stop is owed are stopped (again) and the failure is recorded."""
        down = time.monotonic() - (self._link_lost_at or time.monotonic())
        for d in self.drives:
            if not self.starver.starved(d):
                await d.read_parameters()  # volatile: a power-cycled drive has defaults again
        statuses = [await self._read(d, retries=0) for d in self.drives]
        problem = reconnect_problem(
            statuses, self.drives, self.command, down, self._stopped_late
        ) or self._owed.problem(statuses, commanded=self.command is not None, why=f"link was down {down:.1f} s; ")
        if problem is None:
            log.warning("drive link restored after %.1f s; both drives verified", down)
            return statuses
        log.error("drive link restored after %.1f s; %s; stopping both", down, problem)
        self._trip_handled = True
        await asyncio.shield(self._owed.send(self._owed.again()))
        self.command = None  # with the failure, no await between: wait_settled sees both
        self.fail(problem)
        return statuses
