"""The poll of both drives: heartbeat, published state, link health, trip interlock.

One task (`DrivePoll.run`) reads both drives every `poll_interval` s at a
steady pace. It is the heartbeat the drives' comm-loss watchdog needs, the
source of `state`, and the interlock:
- A drive that trips has both drives ramped to zero before the fault is
  recorded in `failure` (the owner raises it).
- A failed poll is counted (`state.poll_failures`, logged); the link is
  declared lost only after `link_loss_polls` consecutive failures (an isolated
  lost frame on a noisy RS-485 line is tolerated). `fit_heartbeat` lowers the
  count so that link_loss_polls x (poll_interval + timeout) stays below the
  drives' COMM_LOSS_TIMEOUT.
- While the link is down the poll keeps reconnecting; once it is back, both
  drives are verified against `command` before anything goes on: drives found
  tripped or off their reference are stopped and the loss is recorded.
"""

from __future__ import annotations

import asyncio
import dataclasses
import logging
import math
import time
from collections.abc import Sequence

from drives import registers as R
from drives.drive import Drive, DriveStatus
from drives.errors import DriveError, DriveFaultError, DriveLinkError
from drives.limits import fmt_speed
from drives.link import ModbusLink
from drives.state import RigDriveState
from drives.stop import StopSender

log = logging.getLogger(__name__)


async def wait_tick(tick: asyncio.Event, timeout: float) -> None:
    """Wait up to `timeout` s for `tick` (a DrivePoll's publish). A cancellation always gets
    through: `asyncio.wait_for` of Python 3.11 drops one that arrives as the event fires, and an
    abort that cancels a wait for standstill or for the setpoint must not be lost."""
    waiter = asyncio.ensure_future(tick.wait())
    try:
        await asyncio.wait({waiter}, timeout=max(0.0, timeout))
    finally:
        waiter.cancel()


class DrivePoll:
    """Polls the spin and orbit drives on one link; owned by `RigDrives`.

    poll_interval : s between polls of both drives.
    link_loss_polls : consecutive failed polls that declare the link lost;
        `loss_polls_given` (set by the user, not the default) makes lowering it
        in `fit_heartbeat` a warning rather than an info.
    Shared with the owner:
    state : the latest RigDriveState; `tick` is set (and replaced) on every publish.
    command : raw REFs (spin, orbit) while running, else None; the owner sets
        it, the poll clears it when it stops the drives.
    failure : what the poll found (trip, failed verification after a link loss,
        a poll that raised), kept until `acknowledge()`.
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
        self._stops = stops or StopSender(drives)  # the owner's: its stops and these never interleave
        self.poll_interval = poll_interval
        self.link_loss_polls = link_loss_polls
        self._loss_polls_given = loss_polls_given
        self.state = RigDriveState(None, None, link_ok=False)
        self.tick = asyncio.Event()
        self.command: tuple[int, int] | None = None
        self.failure: DriveError | None = None
        self._trip_handled = False
        self._ack_time = 0.0  # polls read before this are stale for trip handling
        self._link_lost_at: float | None = None

    def acknowledge(self) -> None:
        """Forget the recorded failure; trips read before now are not handled again."""
        self.failure = None
        self._trip_handled = False
        self._ack_time = time.monotonic()

    def fail(self, err: DriveError) -> None:
        """Record `err` unless an earlier failure is still unacknowledged."""
        if self.failure is None:
            self.failure = err

    def fit_heartbeat(self) -> None:
        """Lower `link_loss_polls` (and warn) when the drives' watchdog would trip
        before a link loss is declared."""
        watchdogs = [d.params.comm_loss_timeout for d in self.drives if d.params and d.params.comm_loss_timeout]
        if not watchdogs:
            return
        gap = self.link.timeout + self.poll_interval  # longest silence after a lost request
        if gap >= min(watchdogs):
            log.warning(
                "request timeout %.2f s + poll interval %.2f s is not below the drives' "
                "COMM_LOSS_TIMEOUT of %.1f s: a single lost request trips them",
                self.link.timeout,
                self.poll_interval,
                min(watchdogs),
            )
            self.link_loss_polls = 1
        elif self.link_loss_polls * gap >= min(watchdogs):
            fit = max(1, math.ceil(min(watchdogs) / gap) - 1)  # fit x gap < watchdog
            (log.warning if self._loss_polls_given else log.info)(
                "link_loss_polls %d x (request timeout %.2f s + poll interval %.2f s) = %.2f s "
                "is not below the drives' COMM_LOSS_TIMEOUT of %.1f s: the link is declared "
                "lost after %d failed poll(s) instead",
                self.link_loss_polls,
                self.link.timeout,
                self.poll_interval,
                self.link_loss_polls * gap,
                min(watchdogs),
                fit,
            )
            self.link_loss_polls = fit

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
        tick, self.tick = self.tick, asyncio.Event()
        tick.set()

    async def run(self) -> None:
        """Poll until cancelled, every `poll_interval` s; a late poll is not made up."""
        next_t = time.monotonic()
        while True:
            try:
                await self._poll_once()
            except asyncio.CancelledError:
                raise
            except Exception as err:  # a bug must not end the heartbeat
                log.exception("drive poll failed")
                self.fail(DriveError(f"poll failed: {err!r}"))
            next_t += self.poll_interval
            now = time.monotonic()
            if next_t < now:  # late (slow link): poll again now, do not bunch up
                next_t = now
            await asyncio.sleep(next_t - now)

    async def _poll_once(self) -> None:
        try:
            if self.state.link_ok:  # no retry: failed polls in a row bound the time to a declared loss
                statuses = [await d.read_status(retries=0) for d in self.drives]
            else:
                statuses = await self._verify_after_reconnect()
        except DriveError as err:
            self._poll_failed(err)
            return
        self.publish(statuses, link_ok=True)
        await self._check_trips(statuses)

    def _poll_failed(self, err: DriveError) -> None:
        """A poll without valid answers: counted; the link is declared lost after
        `link_loss_polls` in a row. Isolated failures keep `state` (drive
        statuses, time, `polls`) as it was, so nothing takes the old reading for
        a new one."""
        old = self.state
        in_row = old.failed_in_row + 1
        if not old.link_ok or in_row >= self.link_loss_polls:
            self._link_down(err)
            return
        log.warning(
            "drive poll failed (%d in a row; link declared lost at %d): %s",
            in_row,
            self.link_loss_polls,
            err,
        )
        self.state = dataclasses.replace(
            old, poll_failures=old.poll_failures + 1, failed_in_row=in_row, link_error=str(err)
        )

    def _link_down(self, err: DriveError) -> None:
        if self.state.link_ok:
            self._link_lost_at = time.monotonic()
            watchdogs = [d.params.comm_loss_timeout for d in self.drives if d.params]
            log.error(
                "drive link lost (%d failed polls in a row): %s; the drives' comm-loss watchdog "
                "stops them after %s s; reconnecting",
                self.state.failed_in_row + 1,
                err,
                max(watchdogs) if watchdogs else "?",
            )
        self.publish(None, link_ok=False, link_error=str(err))

    async def _verify_after_reconnect(self) -> list[DriveStatus]:
        """Link is back: re-read parameters and check both drives against the command."""
        down = time.monotonic() - (self._link_lost_at or time.monotonic())
        for d in self.drives:
            await d.read_parameters()  # volatile: a power-cycled drive has defaults again
        statuses = [await d.read_status(retries=0) for d in self.drives]
        command = self.command
        problem: DriveError | None = None
        for i, (st, d) in enumerate(zip(statuses, self.drives)):
            if st.tripped:
                problem = DriveFaultError(
                    f"tripped while the link was down ({down:.1f} s)",
                    drive=st.device_id,
                    drive_name=st.name,
                    register=R.FAULT,
                    fault_code=st.fault_code,
                )
                break
            if command is not None:
                want = command[i]
                if not st.running or st.reference_raw != want:
                    problem = DriveLinkError(
                        f"link was down {down:.1f} s; found {st.state} with REF "
                        f"{fmt_speed(st.reference)} instead of running at {fmt_speed(d.speed_of(want))}",
                        drive=st.device_id,
                        drive_name=st.name,
                        register=R.REF,
                    )
                    break
        if problem is None:
            log.warning("drive link restored after %.1f s; both drives verified", down)
            return statuses
        log.error("drive link restored after %.1f s; %s; stopping both", down, problem)
        self._trip_handled = True
        await asyncio.shield(self._stops.send())
        self.command = None
        self.fail(problem)
        return statuses

    async def _check_trips(self, statuses: list[DriveStatus]) -> None:
        tripped = [st for st in statuses if st.tripped and st.time > self._ack_time]
        if not tripped:
            if not any(st.tripped for st in statuses):
                self._trip_handled = False
            return
        if self._trip_handled:
            return
        self._trip_handled = True
        st = tripped[0]
        err = DriveFaultError(
            "tripped",
            drive=st.device_id,
            drive_name=st.name,
            register=R.FAULT,
            fault_code=st.fault_code,
        )
        log.error("%s; ramping both drives to zero", err)
        await asyncio.shield(self._stops.send())  # delivered before anyone hears of the fault
        self.command = None
        self.fail(err)
