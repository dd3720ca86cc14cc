"""Both spindle drives as one controller: limits, heartbeat poll, safe stop.

    limits = DriveLimits(max_spin=300.0, max_orbit=150.0, min_ratio=None, max_ratio=1.0)
    async with RigDrives("tcp://127.0.0.1:5020", limits) as rig:
        await rig.set_speeds(spin=250.0, orbit=-120.0)   # rad/s; orbit < 0: backward whirl
        await rig.wait_settled(hold=2.0, timeout=60.0)
    # leaving the block (normally, on any exception, on cancellation) ramps both to zero

Safety rules this class keeps:
- A speed command is checked against the limits (configured and the drives' own MAX_SPEED,
  spin one direction only) before anything is written; refused: DriveLimitError, nothing sent.
- One named poll task (drives/poll.py) reads both drives every `poll_interval` s: the heartbeat the drives'
  comm-loss watchdog needs, the source of `state`, and the interlock: if either drive trips, both are ramped
  to zero and the fault is raised from `wait_settled`.
- A failed poll is counted (`state.poll_failures`, logged) but the link is declared lost only
  after `link_loss_polls` consecutive failed polls, or once the link has answered nothing (and
  failed) for link_loss_polls x (poll_interval + timeout) s since the last good poll (a stop's
  tries hold the poll's reads). The count is lowered on entry, if needed, so that this time stays
  below the drives' COMM_LOSS_TIMEOUT: the loss is declared before the drives' own watchdog stops
  them (a warning if the count was given).
- On a declared link loss the poll reports it (log, `state.link_ok`), keeps reconnecting and, once the link
  is back, verifies both drives against what was commanded before anything goes on; drives found tripped or off their reference are
  stopped and the loss is raised. A stop a drive missed is owed: a drive found
  running while it is owed gets it again, and that is raised (drives/poll.py); so does a drive
  found running again after a stop both took, no speed commanded since (another client, its keypad).
- A poll task that dies on an exception (a bug outside its polls: nobody watches the drives
  then) is a failure: both drives get its stop, the waits (`wait_settled`, `stop`'s, the exit's
  for a starved drive) end at once, raising a DriveError that names the crash (chained to it),
  `set_speeds` refuses; the exit stops both again and raises that DriveError (the bug itself its
  cause, logged with its traceback as the poll died: drives/poll.py), so a command's one error
  boundary for drive errors says it.
- `stop` (waiting) sends a word not taken for a reason that may pass again until taken (drives/stop_again.py);
  raises StopTripError for a drive that tripped during the stop, once both are at standstill (said) or the wait
  ends; a drive that did not take the stop, its delivery error once the other one is at standstill or the wait ends.
- While a write the link gave up on may still reach a drive (TCP: a start's word after the stop, drives/late.py),
  a waiting `stop` is done only once both are read at rest after that window, and the exit closes the link only once
  both are read not running at REF 0 after it (their ramps not waited out); one read running or at a nonzero REF
  meanwhile gets the stop again (a warning). A cancel during the exit's stop skips that watch.
- Any exception inside `set_speeds`, and every exit of the context, ramps both drives to zero
  (an emergency stop is repeated as such: after one, every stop is one until a new speed is
  commanded, the poll's for a trip in the emergency ramp too, drives/owed.py); the stop is sent
  even while the task is being cancelled. Only `release()` followed by a clean exit leaves them running (the CLI's `run`),
  said once (a warning); not if the poll recorded a failure (it stopped them): the exit stops
  them again and raises it. A drive whose comm-loss watchdog is being starved (it ran on through the stop:
  drives/starve.py) is first waited for until the poll has read it again (about COMM_LOSS_TIMEOUT + 0.6 s at most; one
  that took the OFF3 let through: read in its emergency ramp), so no exit nor waiting `stop` misses it; a second
  cancel skips the wait. Nothing raised in the exit before its stop skips it (drives/way_out.py): a failure there (a
  bug, the poll ended on an exception) is logged, and raised once both drives' stop has gone out and the link is
  closed; a block that raised keeps its own exception, the failure noted on it.
  No start word of `set_speeds` goes out after a stop asked since its call (the poll's on a trip, a
  `stop_now` while it reads the drives' statuses: DriveSuperseded, the stop kept as asked), nor while the poll's stop is going out; a drive it reads stopped or moved by someone else while
  running at the speeds before is not started again (the poll's DriveOffCommand, both stopped).
- On entry, a drive at standstill showing fault 7510 (a previous client went away) is reset; any other fault waits
  for `reset_faults()`. Drives found running are left so (one read in its emergency ramp makes every stop the
  emergency stop until a speed is commanded);
  an entry failing (not cancelled) once connected, a drive read turning or not read, stops both (drives/entry.py).
"""

from __future__ import annotations

import asyncio
import functools
import logging
from collections.abc import Callable
from types import TracebackType

from drives.entry import Entry
from drives.errors import DriveError, DriveFaultError, DriveLinkError, DriveSuperseded, StopTripError
from drives.limits import DriveLimits, fmt_speed
from drives.findings import trip_fault
from drives.late import watch
from drives.link import ModbusLink
from drives.opening import clear_stale_comm_loss, params_to_write, watchdog_words
from drives.pair import drive_names, drive_pair
from drives.poll import DrivePoll
from drives.rig_stop import RigStop
from drives.settle import settled
from drives.state import RigDriveState
from drives.stop import StopSender
from drives.way_out import POLL_END_S, WayOut, end_poll, starved_outcome

log = logging.getLogger(__name__)

__all__ = ["POLL_END_S", "RigDrives", "StopTripError"]


class RigDrives(RigStop):
    """The spin (omega) and orbit (Omega) drives on one Modbus link.

    Parameters
    ----------
    url : `tcp://host:port` or `rtu:///dev/ttyX?baud=19200`.
    limits : DriveLimits, rad/s.
    poll_interval : s between polls of both drives (heartbeat; keep well under the drives' COMM_LOSS_TIMEOUT).
    spin_id, orbit_id : Modbus device ids.
    timeout : s per Modbus request.
    link_loss_polls : consecutive failed polls that declare the link lost (`state.link_ok` False, the
        sweep's interlock); fewer are counted and logged only. None: 3, lowered without a warning to fit the watchdog.
    accel_time, decel_time, comm_loss_timeout : s; written to both drives on entry when given and different
        from what a drive holds (a drive must be stopped to take a new value).
    state_timeout : s for a drive to confirm a state change on its status word.
    """

    def __init__(
        self,
        url: str,
        limits: DriveLimits,
        *,
        poll_interval: float = 0.1,
        spin_id: int = 1,
        orbit_id: int = 2,
        timeout: float = 1.0,
        accel_time: float | None = None,
        decel_time: float | None = None,
        comm_loss_timeout: float | None = None,
        state_timeout: float = 2.0,
        link_loss_polls: int | None = None,
    ):
        if not poll_interval > 0:
            raise ValueError(f"poll_interval {poll_interval} s is not positive")
        loss_polls_given = link_loss_polls is not None
        link_loss_polls = 3 if link_loss_polls is None else link_loss_polls
        if int(link_loss_polls) != link_loss_polls or link_loss_polls < 1:
            raise ValueError(f"link_loss_polls {link_loss_polls} is not a positive integer")
        self.url = url
        self.limits = limits
        self.poll_interval = float(poll_interval)
        self.link = ModbusLink(url, timeout=timeout, names=drive_names(spin_id, orbit_id))
        self.spin, self.orbit = drive_pair(self.link, spin_id, orbit_id, state_timeout=state_timeout)
        self._drives = (self.spin, self.orbit)
        self._stops = StopSender(self._drives)
        self._params = {"accel_time": accel_time, "decel_time": decel_time, "comm_loss_timeout": comm_loss_timeout}
        # state, command (raw REFs while running) and the failure wait_settled raises
        self._poll = DrivePoll(
            self.link,
            self._drives,
            poll_interval=self.poll_interval,
            link_loss_polls=int(link_loss_polls),
            loss_polls_given=loss_polls_given,
            stops=self._stops,
        )
        self._poll_task: asyncio.Task[None] | None = None
        self._release: Callable[[str], None] | None = None  # release(): who says that both run on
        self._emergency = False  # the last stop was an emergency stop: exit repeats it
        self.stop_errors: list[DriveError] = []  # delivery failures of the last stop command
        self.stop_sent = ""  # the last stop command's words as sent ('ramp stop (OFF1)', stop_kind)
        self.stop_again = ""  # what its word sent again did ('' if it went once: drives/stop_again.py)
        self._sent_emergency = False  # the last stop command's word as sent is OFF3
        self.entry = Entry(self._drives)  # what the last entry read and did (a failed one's stop)

    # -- context ----------------------------------------------------------------
    async def __aenter__(self) -> RigDrives:
        entry = self.entry = Entry(self._drives)  # a failure once connected: drives turning stopped (drives/entry.py)
        try:
            await self.link.connect()
            entry.connected = True
            for d in self._drives:
                await d.read_parameters()
            for d in self._drives:
                changed = params_to_write(d.params, self._params)
                if changed:
                    await d.configure(**changed)
            self._poll.fit_heartbeat()
            statuses = [await clear_stale_comm_loss(d) for d in self._drives]
            entry.statuses = {st.device_id: st for st in statuses}
            if any(st.emergency_ramp for st in statuses):  # no ramp stop into it (drives/owed.py)
                self._poll.emergency_found()
            self._poll.publish(statuses, link_ok=True)
            self._poll_task = asyncio.create_task(self._poll.run(), name=f"drives-poll {self.url}")
        except BaseException as err:
            try:
                if entry.connected:
                    await entry.failed(err, lambda emergency: self._safe_stop(emergency=emergency))
            finally:
                await self.link.close()
            raise
        return self

    async def __aexit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        way = WayOut()  # nothing raised before the stop skips it: kept, raised after it (drives/way_out.py)
        task, self._poll_task = self._poll_task, None
        try:
            with way.caught("the wait for the starved drive's outcome"):
                if task is not None and not task.done():
                    await starved_outcome(
                        self._poll, self.link.timeout
                    )  # cancelled: the stop now; a starved drive is not addressed
            if task is not None:
                await end_poll(self._poll, task, way)
            kept = self._release is not None and exc_type is None and not way.cancelled and way.failure is None
            kept = kept and (task is None or task.done())
            if kept and self._poll.failure is None and self._release is not None:  # judged once the poll has ended
                with way.caught("the exit's warning"):
                    words = f"with no client polling them, {watchdog_words(self._drives)}"
                    self._release(f"both drives left running at the setpoint: {words}")
                    return
            try:
                errors = await self._safe_stop(emergency=self._emergency)
                with way.caught("the watch for a write given up"):  # it may start a drive still: drives/late.py
                    again = functools.partial(self._safe_stop, emergency=self._emergency)
                    errors += await watch(self._drives, self.link.late, again, self.stop_sent, self.poll_interval)
            except asyncio.CancelledError:  # raised by _safe_stop after delivering the stop
                way.cancelled, errors = True, []
        finally:
            if task is not None and not task.done():
                task.cancel()
            await self.link.close()
        way.end(exc)
        if errors and exc_type is None:
            raise errors[0]
        if kept and self._poll.failure is not None:  # released, but the poll stopped them: not left running
            raise self._poll.failure

    def release(self, said: Callable[[str], None] | None = None) -> None:
        """Leave the drives running if the context exits without an exception. For the CLI's `run`,
        which returns at setpoint. Any exception or cancellation still stops both drives; once no
        client polls them, their own comm-loss watchdog ramps them down if it is armed
        (COMM_LOSS_TIMEOUT > 0: give `comm_loss_timeout` on entry); the exit's warning ("both drives
        left running at the setpoint: ...") says whether it was, as last read, handed to ``said``
        (the CLI's terminal; None: this module's log): one it fails to say stops both and is raised
        by the exit. A failure the poll recorded by the exit (it stopped both) is raised by the exit,
        after the stop sent again, and nothing is left running; so is a poll ended on an exception."""
        self._release = said or (lambda words: log.warning("%s", words))

    # -- commands ---------------------------------------------------------------
    @property
    def state(self) -> RigDriveState:
        """The latest poll (per drive status bits, speeds rad/s, torque, fault code, link)."""
        return self._poll.state

    @property
    def link_loss_polls(self) -> int:
        """Consecutive failed polls that declare the link lost (as fitted on entry)."""
        return self._poll.link_loss_polls

    def check(self) -> RigDriveState:
        """The latest poll, or raise what the poll found (a trip as DriveFaultError,
        a failed verification after a link loss), as `wait_settled` does.

        For a caller holding the drives at speed (the CLI's `run --hold`).
        """
        self._require_open()
        if self._poll.failure is not None:
            raise self._poll.failure
        self._poll.alive()
        return self._poll.state

    async def set_speeds(self, spin: float, orbit: float) -> tuple[float, float]:
        """Run the spin drive at `spin` rad/s (>= 0) and the orbit drive at `orbit` rad/s; returns the
        speeds as written (rad/s, spin and orbit): each REF rounded to its count (0.15 rpm at
        SPEED_SCALE 3000 rpm), at the drive's own scale (`Drive.speed_of`).

        `orbit` > 0 is forward whirl, < 0 backward. Limits are checked before anything is written
        (DriveLimitError, nothing sent); a tripped drive, or a failure the poll found (latched:
        raised again), is refused until `reset_faults`. Returns once both drives report operation
        enabled; use `wait_settled` for the speed. Any failure after the check ramps both drives to
        zero; a stop asked meanwhile (the poll's on a trip, `stop_now`, also while the drives are read)
        ends the start, none of its words after the stop (the trip raised, else DriveSuperseded). A drive read off the speeds it was running at (stopped by
        another client, at its keypad) is that poll's finding: both stopped, raised, not restarted."""
        self._require_open()
        self.limits.check(spin, orbit, spin_id=self.spin.device_id, orbit_id=self.orbit.device_id)
        refs = (self.spin.reference_for(spin), self.orbit.reference_for(orbit))
        self._poll.alive()  # nobody would watch them: nothing commanded
        if not self._poll.state.link_ok:
            raise DriveLinkError(f"link to the drives is down ({self._poll.state.link_error}); nothing commanded")
        asked = self._stops.asked  # a stop asked from here on ends the start (an abort's during the reads too)
        try:
            statuses = [await d.read_status() for d in self._drives]
            for st in statuses:
                if st.tripped:
                    raise trip_fault(st, "tripped; call reset_faults() before commanding speeds")
            await self._poll.check_following(statuses)  # one stopped elsewhere is not started again
            found = self._poll.failure or self._poll.stopping_for  # the poll stopped both: no start undoes it
            if found is not None:
                raise found
            if self._stops.asked != asked:  # before anything forgets that stop (an emergency stop stays one)
                raise DriveSuperseded("nothing commanded: a stop was asked while the drives were read")
            self._emergency = False
            self._poll.commanded(refs)
            following = all(st.following for st in statuses)  # a new REF at most
            for d, st in zip(self._drives, statuses):  # one in local control refuses it before any run word
                if not st.following:
                    await d.ready(guard=lambda: self._stops.asked == asked)
            for d, raw, st in zip(self._drives, refs, statuses):  # no word after a stop asked since
                await d.start(raw, st if following else None, guard=lambda: self._stops.asked == asked)
            self._poll.started()
            log.info("drives commanded: spin %s, orbit %s", fmt_speed(spin), fmt_speed(orbit))
            return self.spin.speed_of(refs[0]), self.orbit.speed_of(refs[1])
        except BaseException as err:
            if isinstance(err, DriveFaultError) and err.fault_code:
                self._poll.fail(err)  # a trip known: the stop after it does not report it again
            await self._safe_stop(emergency=self._emergency)  # an abort's stop_now stays an emergency
            if isinstance(err, DriveSuperseded) and self._poll.failure is not None:
                raise self._poll.failure from err  # the poll's stop (a trip): said as what it is
            raise

    async def wait_settled(self, *, hold: float, timeout: float, expect: float | None = None) -> RigDriveState:
        """Return once both drives have held AT_SETPOINT of the commanded references for `hold` s
        (polled state; drives/settle.py). First status: at once, or at `expect` (monotonic s, the
        ramps' end). Raises the fault (DriveFaultError with its code) or link loss (DriveLinkError)
        the poll found, its crash (a DriveError: nobody watches the drives, both stopped), or
        DriveTimeoutError after `timeout` s.
        """
        self._require_open()
        return await settled(self._poll, hold=hold, timeout=timeout, expect=expect)

    async def reset_faults(self) -> None:
        """Reset both drives' faults (RESET edge); DriveFaultError if a cause is still active."""
        self._require_open()
        errors = []
        for d in self._drives:
            try:
                await d.reset_fault()
            except DriveError as err:
                errors.append(err)
        if errors:
            raise errors[0]
        self._poll.acknowledge()
