"""Both spindle drives as one controller: limits, heartbeat poll, safe stop.

    limits = DriveLimits(max_spin=300.0, max_orbit=150.0, min_ratio=None, max_ratio=1.0)
    async with RigDrives("tcp://127.0.0.1:5020", limits) as rig:
        await rig.set_speeds(spin=250.0, orbit=-120.0)   # rad/s; orbit < 0: backward whirl
        await rig.wait_settled(hold=2.0, timeout=60.0)
        ...
    # leaving the block (normally, on any exception, on cancellation) ramps both to zero

Safety rules this class keeps:
- A speed command is checked against the limits (configured and the drives'
  own MAX_SPEED, spin one direction only) before anything is written; a
  refused command raises DriveLimitError and sends nothing.
- One named poll task reads both drives every `poll_interval` s at a steady
  pace. It is the heartbeat the drives' comm-loss watchdog needs, the source of
  `state`, and the interlock: if either drive trips, both are ramped to zero
  and the fault is raised from `wait_settled`.
- A failed poll is counted (`state.poll_failures`, logged) but the link is
  declared lost only after `link_loss_polls` consecutive failed polls (an
  isolated lost frame on a noisy RS-485 line is tolerated). The count is
  lowered on entry, if needed, so that link_loss_polls x (poll_interval +
  timeout) stays below the drives' COMM_LOSS_TIMEOUT: the loss is declared
  before the drives' own watchdog stops them (a warning if the count was
  given explicitly).
- On a declared link loss the poll reports it (log, `state.link_ok`), keeps
  reconnecting and, once the link is back, verifies both drives against what was commanded
  before anything goes on; drives found tripped or off their reference are
  stopped and the loss is raised.
- Any exception inside `set_speeds`, and every exit of the context, ramps both
  drives to zero (an emergency stop is repeated as such); the stop is sent
  even while the task is being cancelled. Only `release()` followed by a clean
  exit leaves them running (the CLI's `run`).
- On entry, a drive at standstill showing fault 7510 (a previous client went
  away) is reset; any other fault waits for `reset_faults()`.
"""

from __future__ import annotations

import asyncio
import dataclasses
import logging
import math
import time
from dataclasses import dataclass

from drives import registers as R
from drives.drive import Drive, DriveStatus, SettleDetector, rad_s_to_rpm
from drives.errors import (
    DriveError,
    DriveFaultError,
    DriveLimitError,
    DriveLinkError,
    DriveTimeoutError,
)
from drives.link import ModbusLink
from drives.pair import drive_names, drive_pair

log = logging.getLogger(__name__)


def _fmt(speed: float) -> str:
    return f"{speed:.3f} rad/s ({rad_s_to_rpm(speed):.1f} rpm)"


async def send_stop(drives, *, emergency: bool = False) -> list[DriveError]:
    """Stop words to every drive (OFF1 ramp stop, or OFF3 emergency stop), then
    zero references so that no later start jumps back to the old speed.

    Control words go out first, to all drives, before anything else; a drive
    that does not take it does not keep the others from getting theirs: each
    gets one try first, and only then are the timed-out ones retried
    (`Drive.write_retries`), so one silent drive delays the other's stop word by
    one request timeout, not by all its retries.
    Returns the delivery errors (logged), one per drive that missed its stop word.
    """
    word = R.CW_EMERGENCY_STOP if emergency else R.CW_RAMP_STOP
    errors = await _to_each(drives, lambda d, retries: d.write_control(word, retries=retries))
    for err in errors:
        log.error("stop command not delivered: %s", err)
    for err in await _to_each(drives, lambda d, retries: d.write_reference(0, retries=retries)):
        log.warning("zero reference not delivered: %s", err)
    return errors


async def _to_each(drives, write) -> list[DriveError]:
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
        except DriveError as err:
            errors[id(d)] = err
    for d in timed_out:
        if d.write_retries < 1:
            continue
        log.warning("%s drive (id %d): write timed out; retrying", d.name, d.device_id)
        try:
            await write(d, d.write_retries - 1)
            del errors[id(d)]
        except DriveError as err:
            errors[id(d)] = err
    return [errors[id(d)] for d in drives if id(d) in errors]


@dataclass(frozen=True)
class DriveLimits:
    """Allowed operating range, rad/s.

    max_spin : largest spin speed omega (spin is >= 0).
    max_orbit : largest |Omega| (orbit is signed).
    min_ratio, max_ratio : allowed |Omega| / omega while both turn, None =
        unbounded. Omega = 0 (orbit spindle still) passes; omega = 0 with
        Omega != 0 (orbit without spin, ratio infinite) fails any ratio bound.
    """

    max_spin: float
    max_orbit: float
    min_ratio: float | None = None
    max_ratio: float | None = None

    def __post_init__(self) -> None:
        for name, value in (("max_spin", self.max_spin), ("max_orbit", self.max_orbit),
                            ("min_ratio", self.min_ratio), ("max_ratio", self.max_ratio)):
            if value is not None and not value >= 0:
                raise ValueError(f"DriveLimits.{name} = {value} must be >= 0")
        if self.min_ratio is not None and self.max_ratio is not None:
            if self.min_ratio > self.max_ratio:
                raise ValueError(
                    f"DriveLimits.min_ratio = {self.min_ratio} > max_ratio = {self.max_ratio}"
                )

    def check(self, spin: float, orbit: float, *, spin_id: int = 1, orbit_id: int = 2) -> None:
        """Raise DriveLimitError if (spin, orbit) is outside the limits (pure)."""
        if not (math.isfinite(spin) and math.isfinite(orbit)):
            raise DriveLimitError(f"speeds must be finite (spin {spin}, orbit {orbit})")
        if spin < 0:
            raise DriveLimitError(
                f"spin {_fmt(spin)} is negative; the spin drive turns one way only",
                drive=spin_id, drive_name="spin", register=R.REF,
            )
        if spin > self.max_spin:
            raise DriveLimitError(
                f"spin {_fmt(spin)} exceeds the limit max_spin = {_fmt(self.max_spin)}",
                drive=spin_id, drive_name="spin", register=R.REF,
            )
        if abs(orbit) > self.max_orbit:
            raise DriveLimitError(
                f"orbit |{_fmt(orbit)}| exceeds the limit max_orbit = {_fmt(self.max_orbit)}",
                drive=orbit_id, drive_name="orbit", register=R.REF,
            )
        if self.min_ratio is None and self.max_ratio is None or orbit == 0:
            return
        ratio = math.inf if spin == 0 else abs(orbit) / spin
        lo = self.min_ratio if self.min_ratio is not None else 0.0
        hi = self.max_ratio if self.max_ratio is not None else math.inf
        if not lo <= ratio <= hi or math.isinf(ratio):
            raise DriveLimitError(
                f"|Omega|/omega = {ratio:.4g} (orbit {_fmt(orbit)}, spin {_fmt(spin)}) "
                f"is outside the allowed range [{lo:g}, {hi:g}]"
            )


@dataclass(frozen=True)
class RigDriveState:
    """The latest poll of both drives. Speeds in the DriveStatus objects are rad/s."""

    spin: DriveStatus | None
    orbit: DriveStatus | None
    link_ok: bool
    link_error: str | None = None
    link_losses: int = 0
    polls: int = 0  # successful polls
    poll_failures: int = 0  # failed polls in all (isolated ones and those of a declared loss)
    failed_in_row: int = 0  # consecutive failed polls up to now (0 after a good one)
    time: float = 0.0  # time.monotonic() of the poll

    @property
    def at_setpoint(self) -> bool:
        return bool(self.spin and self.orbit and self.spin.at_setpoint and self.orbit.at_setpoint)

    @property
    def stopped(self) -> bool:
        """Both drives read an actual speed of exactly zero."""
        return bool(self.spin and self.orbit and self.spin.stopped and self.orbit.stopped)

    def to_dict(self) -> dict:
        return {
            "link_ok": self.link_ok,
            "link_error": self.link_error,
            "link_losses": self.link_losses,
            "poll_failures": self.poll_failures,
            "spin": self.spin.to_dict() if self.spin else None,
            "orbit": self.orbit.to_dict() if self.orbit else None,
        }


class RigDrives:
    """The spin (omega) and orbit (Omega) drives on one Modbus link.

    Parameters
    ----------
    url : `tcp://host:port` or `rtu:///dev/ttyX?baud=19200`.
    limits : DriveLimits, rad/s.
    poll_interval : s between polls of both drives (heartbeat; keep well under
        the drives' COMM_LOSS_TIMEOUT).
    spin_id, orbit_id : Modbus device ids.
    timeout : s per Modbus request.
    link_loss_polls : consecutive failed polls that declare the link lost
        (`state.link_ok` False, the sweep's interlock); fewer are counted and
        logged only. None: 3, lowered without a warning to fit the watchdog.
    accel_time, decel_time, comm_loss_timeout : s; written to both drives on
        entry when given (the drives must be stopped then).
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
        self._loss_polls_given = link_loss_polls is not None
        if link_loss_polls is None:
            link_loss_polls = 3
        if int(link_loss_polls) != link_loss_polls or link_loss_polls < 1:
            raise ValueError(f"link_loss_polls {link_loss_polls} is not a positive integer")
        self.link_loss_polls = int(link_loss_polls)
        self.url = url
        self.limits = limits
        self.poll_interval = float(poll_interval)
        self.link = ModbusLink(url, timeout=timeout, names=drive_names(spin_id, orbit_id))
        self.spin, self.orbit = drive_pair(self.link, spin_id, orbit_id, state_timeout=state_timeout)
        self._drives = (self.spin, self.orbit)
        self._params = {"accel_time": accel_time, "decel_time": decel_time,
                        "comm_loss_timeout": comm_loss_timeout}
        self._state = RigDriveState(None, None, link_ok=False)
        self._tick = asyncio.Event()
        self._poll_task: asyncio.Task | None = None
        self._command: tuple[int, int] | None = None  # raw REFs (spin, orbit) while running
        self._failure: DriveError | None = None  # raised by wait_settled until acknowledged
        self._trip_handled = False
        self._ack_time = 0.0  # polls read before this are stale for trip handling
        self._link_lost_at: float | None = None
        self._release = False
        self._emergency = False  # the last stop was an emergency stop: exit repeats it
        self.stop_errors: list[DriveError] = []  # delivery failures of the last stop command

    # -- context ----------------------------------------------------------------
    async def __aenter__(self) -> RigDrives:
        try:
            await self.link.connect()
            for d in self._drives:
                await d.read_parameters()
            if any(v is not None for v in self._params.values()):
                for d in self._drives:
                    await d.configure(**self._params)
            self._check_heartbeat_margin()
            statuses = [await self._clear_stale_comm_loss(d) for d in self._drives]
            self._publish(statuses, link_ok=True)
            self._poll_task = asyncio.create_task(
                self._poll_loop(), name=f"drives-poll {self.url}"
            )
        except BaseException:
            await self.link.close()
            raise
        return self

    async def __aexit__(self, exc_type, exc, tb) -> None:
        cancelled = False
        try:
            task, self._poll_task = self._poll_task, None
            if task is not None:
                task.cancel()
                try:
                    await asyncio.wait([task])
                except asyncio.CancelledError:  # cancelled again: stop the drives first
                    cancelled = True
            if self._release and exc_type is None:
                log.warning(
                    "drives left running at their setpoint; without a polling client their "
                    "comm-loss watchdog ramps them down"
                )
                return
            try:
                errors = await self._safe_stop(emergency=self._emergency)
            except asyncio.CancelledError:  # raised by _safe_stop after delivering the stop
                cancelled, errors = True, []
            if cancelled:
                raise asyncio.CancelledError
            if errors and exc_type is None:
                raise errors[0]
        finally:
            await self.link.close()

    def _check_heartbeat_margin(self) -> None:
        """Lower `link_loss_polls` (and warn) when the drives' watchdog would trip
        before a link loss is declared."""
        watchdogs = [d.params.comm_loss_timeout for d in self._drives if d.params.comm_loss_timeout]
        if not watchdogs:
            return
        gap = self.link.timeout + self.poll_interval  # longest silence after a lost request
        if gap >= min(watchdogs):
            log.warning(
                "request timeout %.2f s + poll interval %.2f s is not below the drives' "
                "COMM_LOSS_TIMEOUT of %.1f s: a single lost request trips them",
                self.link.timeout, self.poll_interval, min(watchdogs),
            )
            self.link_loss_polls = 1
        elif self.link_loss_polls * gap >= min(watchdogs):
            fit = max(1, math.ceil(min(watchdogs) / gap) - 1)  # fit x gap < watchdog
            (log.warning if self._loss_polls_given else log.info)(
                "link_loss_polls %d x (request timeout %.2f s + poll interval %.2f s) = %.2f s "
                "is not below the drives' COMM_LOSS_TIMEOUT of %.1f s: the link is declared "
                "lost after %d failed poll(s) instead",
                self.link_loss_polls, self.link.timeout, self.poll_interval,
                self.link_loss_polls * gap, min(watchdogs), fit,
            )
            self.link_loss_polls = fit

    async def _clear_stale_comm_loss(self, drive: Drive) -> DriveStatus:
        """A drive at standstill showing fault 7510 (the previous client went away)
        is reset: talking to it removed the cause. Other faults stay for
        `reset_faults`; a reset the drive refuses leaves it tripped."""
        st = await drive.read_status()
        if st.tripped and st.fault_code == R.FAULT_COMM_LOSS and st.stopped:
            log.warning(
                "%s drive (id %d): resetting fault 7510 left by a previous client (at standstill)",
                drive.name, drive.device_id,
            )
            try:
                st = await drive.reset_fault()
            except DriveFaultError as err:
                log.warning("%s", err)
                st = await drive.read_status()
        return st

    def release(self) -> None:
        """Leave the drives running if the context exits without an exception.

        For the CLI's `run`, which returns at setpoint. Any exception or
        cancellation still stops both drives; once no client polls them, the
        drives' own comm-loss watchdog ramps them down.
        """
        self._release = True

    # -- commands ---------------------------------------------------------------
    @property
    def state(self) -> RigDriveState:
        """The latest poll (per drive status bits, speeds rad/s, torque, fault code, link)."""
        return self._state

    def check(self) -> RigDriveState:
        """The latest poll, or raise what the poll found (a trip as DriveFaultError,
        a failed verification after a link loss), as `wait_settled` does.

        For a caller holding the drives at speed (the CLI's `run --hold`).
        """
        self._require_open()
        if self._failure is not None:
            raise self._failure
        return self._state

    async def set_speeds(self, spin: float, orbit: float) -> None:
        """Run the spin drive at `spin` rad/s (>= 0) and the orbit drive at `orbit` rad/s.

        `orbit` > 0 is forward whirl, < 0 backward. Limits are checked before
        anything is written (DriveLimitError, nothing sent); a tripped drive
        is refused (DriveFaultError; `reset_faults` first). Returns once both
        drives report operation enabled; use `wait_settled` for the speed.
        Any failure after the check ramps both drives to zero.
        """
        self._require_open()
        self.limits.check(spin, orbit, spin_id=self.spin.device_id, orbit_id=self.orbit.device_id)
        refs = (self.spin.reference_for(spin), self.orbit.reference_for(orbit))
        if not self._state.link_ok:
            raise DriveLinkError(
                f"link to the drives is down ({self._state.link_error}); nothing commanded"
            )
        try:
            statuses = [await d.read_status() for d in self._drives]
            for st in statuses:
                if st.tripped:
                    raise DriveFaultError(
                        "tripped; call reset_faults() before commanding speeds",
                        drive=st.device_id, drive_name=st.name, register=R.FAULT,
                        fault_code=st.fault_code,
                    )
            self._acknowledge()
            self._emergency = False
            self._command = refs
            for d, raw in zip(self._drives, refs):
                await d.start(raw)
            log.info("drives commanded: spin %s, orbit %s", _fmt(spin), _fmt(orbit))
        except BaseException:
            self._command = None
            await self._safe_stop()
            raise

    async def wait_settled(self, *, hold: float, timeout: float) -> RigDriveState:
        """Return once both drives have held AT_SETPOINT for `hold` s (polled state).

        Raises the fault (DriveFaultError with its code) or link loss
        (DriveLinkError) the poll found, or DriveTimeoutError after `timeout` s.
        While the link is down the hold restarts; the wait goes on only after
        the reconnect has verified both drives.
        """
        self._require_open()
        detector = SettleDetector(hold)
        deadline = time.monotonic() + timeout
        last_poll = -1
        while True:
            tick = self._tick
            if self._failure is not None:
                raise self._failure
            if self._command is None:
                raise DriveError("no speeds commanded: call set_speeds() first")
            st = self._state
            if st.polls != last_poll:
                last_poll = st.polls
                if not st.link_ok:
                    detector.reset()
                elif detector.update(st.at_setpoint, st.time):
                    return st
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise DriveTimeoutError(
                    f"not at setpoint (AT_SETPOINT held {hold:g} s) within {timeout:g} s: "
                    + self._describe(st),
                    register=R.SW,
                )
            try:
                await asyncio.wait_for(tick.wait(), remaining)
            except asyncio.TimeoutError:
                pass

    async def stop(
        self, *, emergency: bool = False, wait: bool = True, timeout: float | None = None
    ) -> None:
        """Ramp both drives to zero (OFF1), or emergency-stop them (OFF3).

        Sends the stop to both drives even if one fails (then raises the first
        error). With `wait`, returns once both read an actual speed of zero;
        `timeout` defaults to the drives' own ramp time from the present speed
        plus a margin.
        """
        self._require_open()
        self._command = None
        self._emergency = emergency
        t_cmd = time.monotonic()
        errors = await self._safe_stop(emergency=emergency)
        if errors:
            raise errors[0]
        if not wait:
            return
        if timeout is None:
            timeout = self._stop_time(emergency)
        deadline = t_cmd + timeout
        while True:
            tick = self._tick
            st = self._state
            if st.link_ok and st.time > t_cmd and st.stopped:
                return
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise DriveTimeoutError(
                    f"drives not at zero speed within {timeout:g} s: " + self._describe(st),
                    register=R.ACT,
                )
            try:
                await asyncio.wait_for(tick.wait(), remaining)
            except asyncio.TimeoutError:
                pass

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
        self._acknowledge()

    # -- internals --------------------------------------------------------------
    def _require_open(self) -> None:
        if self._poll_task is None:
            raise DriveError("RigDrives is not open: use `async with RigDrives(...)`")

    def _acknowledge(self) -> None:
        self._failure = None
        self._trip_handled = False
        self._ack_time = time.monotonic()

    def _fail(self, err: DriveError) -> None:
        if self._failure is None:
            self._failure = err

    def _stop_time(self, emergency: bool) -> float:
        """Default wait for standstill (s): the drives' own ramp from the present
        speed, with margin; a tripped drive coasts at a rate nobody knows, so it
        gets a minute more."""
        worst = 0.0
        for d, st in ((self.spin, self._state.spin), (self.orbit, self._state.orbit)):
            if d.params is None or st is None:
                continue
            t = d.params.decel_time * abs(st.actual) / d.params.speed_scale
            t = t / 10 if emergency else t
            worst = max(worst, t + (60.0 if st.tripped else 0.0))
        return 1.5 * worst + 2.0 + 4 * self.poll_interval

    def _describe(self, st: RigDriveState) -> str:
        parts = []
        for s in (st.spin, st.orbit):
            if s is not None:
                parts.append(
                    f"{s.name} (id {s.device_id}) {s.state}, REF {_fmt(s.reference)}, "
                    f"ACT {_fmt(s.actual)}, fault {s.fault_code}"
                )
        if not st.link_ok:
            parts.append(f"link down: {st.link_error}")
        return "; ".join(parts)

    def _publish(self, statuses, *, link_ok: bool, link_error: str | None = None) -> None:
        old = self._state
        spin, orbit = statuses if statuses else (old.spin, old.orbit)
        self._state = RigDriveState(
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
        tick, self._tick = self._tick, asyncio.Event()
        tick.set()

    async def _safe_stop(self, *, emergency: bool = False) -> list[DriveError]:
        """Deliver the stop to both drives even if the calling task is cancelled meanwhile.

        Returns the delivery errors (logged); a cancellation that arrived
        during the stop is re-raised once the stop has been sent.
        """
        task = asyncio.get_running_loop().create_task(
            send_stop(self._drives, emergency=emergency), name="drives-safe-stop"
        )
        cancelled = False
        while not task.done():
            try:
                await asyncio.shield(task)
            except asyncio.CancelledError:
                cancelled = True
        self.stop_errors = task.result()
        if cancelled:
            raise asyncio.CancelledError
        return self.stop_errors

    async def _poll_loop(self) -> None:
        next_t = time.monotonic()
        while True:
            try:
                await self._poll_once()
            except asyncio.CancelledError:
                raise
            except Exception as err:  # a bug must not end the heartbeat
                log.exception("drive poll failed")
                self._fail(DriveError(f"poll failed: {err!r}"))
            next_t += self.poll_interval
            now = time.monotonic()
            if next_t < now:  # late (slow link): poll again now, do not bunch up
                next_t = now
            await asyncio.sleep(next_t - now)

    async def _poll_once(self) -> None:
        try:
            if self._state.link_ok:
                statuses = [await d.read_status() for d in self._drives]
            else:
                statuses = await self._verify_after_reconnect()
        except DriveError as err:
            self._poll_failed(err)
            return
        self._publish(statuses, link_ok=True)
        await self._check_trips(statuses)

    def _poll_failed(self, err: DriveError) -> None:
        """A poll without valid answers: counted; the link is declared lost after
        `link_loss_polls` in a row. Isolated failures keep `state` (drive
        statuses, time, `polls`) as it was, so nothing takes the old reading for
        a new one."""
        old = self._state
        in_row = old.failed_in_row + 1
        if not old.link_ok or in_row >= self.link_loss_polls:
            self._link_down(err)
            return
        log.warning(
            "drive poll failed (%d in a row; link declared lost at %d): %s",
            in_row, self.link_loss_polls, err,
        )
        self._state = dataclasses.replace(
            old, poll_failures=old.poll_failures + 1, failed_in_row=in_row, link_error=str(err)
        )

    def _link_down(self, err: DriveError) -> None:
        if self._state.link_ok:
            self._link_lost_at = time.monotonic()
            watchdogs = [d.params.comm_loss_timeout for d in self._drives if d.params]
            log.error(
                "drive link lost (%d failed polls in a row): %s; the drives' comm-loss watchdog "
                "stops them after %s s; reconnecting",
                self._state.failed_in_row + 1,
                err,
                max(watchdogs) if watchdogs else "?",
            )
        self._publish(None, link_ok=False, link_error=str(err))

    async def _verify_after_reconnect(self) -> list[DriveStatus]:
        """Link is back: re-read parameters and check both drives against the command."""
        down = time.monotonic() - (self._link_lost_at or time.monotonic())
        for d in self._drives:
            await d.read_parameters()  # volatile: a power-cycled drive has defaults again
        statuses = [await d.read_status() for d in self._drives]
        command = self._command
        problem: DriveError | None = None
        for i, (st, d) in enumerate(zip(statuses, self._drives)):
            if st.tripped:
                problem = DriveFaultError(
                    f"tripped while the link was down ({down:.1f} s)",
                    drive=st.device_id, drive_name=st.name, register=R.FAULT,
                    fault_code=st.fault_code,
                )
                break
            if command is not None:
                want = command[i]
                if not st.running or st.reference_raw != want:
                    problem = DriveLinkError(
                        f"link was down {down:.1f} s; found {st.state} with REF "
                        f"{_fmt(st.reference)} instead of running at {_fmt(d.speed_of(want))}",
                        drive=st.device_id, drive_name=st.name, register=R.REF,
                    )
                    break
        if problem is None:
            log.warning("drive link restored after %.1f s; both drives verified", down)
            return statuses
        log.error("drive link restored after %.1f s; %s; stopping both", down, problem)
        self._trip_handled = True
        await send_stop(self._drives)
        self._command = None
        self._fail(problem)
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
            "tripped", drive=st.device_id, drive_name=st.name, register=R.FAULT,
            fault_code=st.fault_code,
        )
        log.error("%s; ramping both drives to zero", err)
        await send_stop(self._drives)  # delivered before anyone hears of the fault
        self._command = None
        self._fail(err)
