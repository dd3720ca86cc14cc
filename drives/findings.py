"""What a poll of both drives can find wrong, worded as the failure to record (pure: no I/O).

- `trip_fault`: a drive reading TRIPPED, as DriveFaultError naming drive, register FAULT and code.
- `reconnect_problem`: after a link loss, a drive found tripped, or (a speed commanded) not
  running at its reference under network control (`drives.state.off_command`).
- `running_while_owed`: with no speed commanded and a stop owed, a drive found running or
  with a nonzero REF: the stop it missed is sent again.
- `running_after_stop`: with no speed commanded since a stop both drives took, a drive found
  running (operation enabled) again: started by another client or at the drive; the stop is
  sent again.
- `defies_stop`, `starved_outcome`, `emergency_outcome`: a drive that keeps running through the
  stop sent again (drives/starve.py): its comm-loss watchdog starved, or why that cannot stop it;
  what it showed when read again, or read in the emergency ramp of the OFF3 let through to it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from drives import registers as R
from drives.drive import Drive, DriveParameters, DriveStatus
from drives.errors import DriveError, DriveFaultError, DriveLinkError, DriveOffCommand
from drives.limits import fmt_speed
from drives.state import off_command
from drives.stop_said import stop_kind


def trip_fault(st: DriveStatus, what: str = "tripped") -> DriveFaultError:
    """DriveFaultError for the tripped drive of `st`: `what`, its id, name, register FAULT, its code."""
    return DriveFaultError(what, drive=st.device_id, drive_name=st.name, register=R.FAULT, fault_code=st.fault_code)


def reconnect_problem(
    statuses: Sequence[DriveStatus],
    drives: tuple[Drive, Drive],
    command: tuple[int, int] | None,
    down: float,
    cause: Callable[[DriveStatus], str | None] = lambda st: None,
) -> DriveError | None:
    """The first drive of `statuses` found tripped, or (`command`: raw REFs spin, orbit) not running
    at its reference under network control, after the link was down `down` s; None if none.
    `cause`: off_command's (a late stop word of ours: drives/late.stopped_late)."""
    for st in statuses:
        if st.tripped:
            return trip_fault(st, f"tripped while the link was down ({down:.1f} s)")
    off = None if command is None else off_command(statuses, drives, command, cause)
    if off is None:
        return None
    return DriveLinkError(
        f"link was down {down:.1f} s; found it {off.reason}",
        drive=off.drive,
        drive_name=off.drive_name,
        register=off.register,
    )


def running_while_owed(statuses: Sequence[DriveStatus], *, emergency: bool, why: str = "") -> DriveLinkError | None:
    """The first drive of `statuses` running or with a nonzero REF while no speed is commanded and
    a stop is owed (`emergency`: the owed stop is OFF3), as the failure; `why` leads the message.
    None if neither drive moves (the stop owed is not needed any more)."""
    moving = [st for st in statuses if st.running or st.reference_raw != 0]
    if not moving:
        return None
    st, kind = moving[0], stop_kind(emergency)
    return DriveLinkError(
        f"{why}found {st.state} with REF {fmt_speed(st.reference)} while no speed is commanded: "
        f"the {kind} it missed (not delivered) is sent again",
        drive=st.device_id,
        drive_name=st.name,
        register=R.CW,
    )


def running_after_stop(statuses: Sequence[DriveStatus], *, emergency: bool, why: str = "") -> DriveOffCommand | None:
    """The first drive of `statuses` running (operation enabled) although it took the stop since
    which no speed was commanded (`emergency`: that stop was OFF3), as the failure; `why` leads
    the message. None if neither runs."""
    running = [st for st in statuses if st.running]
    if not running:
        return None
    st, kind = running[0], stop_kind(emergency)
    local = "" if st.remote else ", in local control (SW REMOTE = 0)"
    return DriveOffCommand(
        f"{why}found {st.state}{local}, REF {fmt_speed(st.reference)}, ACT {fmt_speed(st.actual)}, after the "
        f"stop it took, no speed commanded since: started again by another client or at the drive; "
        f"the {kind} is sent again",
        drive=st.device_id,
        drive_name=st.name,
        register=R.SW,
    )


def defies_stop(st: DriveStatus, params: DriveParameters | None, *, since: float, took: bool) -> DriveFaultError:
    """`st`'s drive found running (operation enabled) `since` s after a stop it `took` (else: it
    missed), sent again every poll, as the failure: its comm-loss watchdog is starved (no request
    to it until it trips fault 7510), or, COMM_LOSS_TIMEOUT reading 0 or unknown, nothing over
    the network can stop it. Register COMM_LOSS_TIMEOUT."""
    local = ", in local control (SW REMOTE = 0: its watchdog may be disarmed)" if not st.remote else ""
    found = (
        f"found {st.state}{local}, REF {fmt_speed(st.reference)}, ACT {fmt_speed(st.actual)}, {since:.1f} s after "
        f"the stop it {'took' if took else 'missed'} (sent again every poll)"
    )
    timeout = None if params is None else params.comm_loss_timeout
    if not timeout:
        why = "reads 0 (no watchdog)" if timeout == 0 else "is not known (parameters not read)"
        end = f"; its COMM_LOSS_TIMEOUT {why}: nothing over the network can stop it; use the rig's emergency stop"
    else:
        end = (
            f": no request goes to it (the other drive is still polled) until its comm-loss watchdog "
            f"({timeout:g} s) trips fault 7510, which ramps it down"
        )
    return DriveFaultError(found + end, drive=st.device_id, drive_name=st.name, register=R.COMM_LOSS_TIMEOUT)


def starved_outcome(st: DriveStatus, before: DriveStatus, silent: float) -> DriveFaultError:
    """What `st` shows, read again after `silent` s without a request (`before`: read when the
    starving began): tripped (fault 7510: its watchdog stopped it) and slowing, or still running
    (nothing over the network can stop it: the rig's emergency stop), as the failure."""
    read = f"read again after {silent:.1f} s without a request: ACT {fmt_speed(st.actual)} (was {fmt_speed(before.actual)})"
    slowing = st.stopped or abs(st.actual) < abs(before.actual)
    if st.tripped:
        what = "tripped by its comm-loss watchdog" if st.fault_code == R.FAULT_COMM_LOSS else "tripped"
        pace = "at standstill" if st.stopped else "slowing" if slowing else "not slowing yet"
        return DriveFaultError(
            f"{read}, {what}, {pace}",
            register=R.FAULT,
            fault_code=st.fault_code,
            drive=st.device_id,
            drive_name=st.name,
        )
    if st.running and not st.stopped:
        return DriveFaultError(
            f"{read}, still {st.state}: its comm-loss watchdog did not stop it; nothing over the network "
            "can stop it: use the rig's emergency stop",
            register=R.SW,
            drive=st.device_id,
            drive_name=st.name,
        )
    now = "not turning" if st.stopped else "not running"
    return DriveFaultError(
        f"{read}, {st.state}, not tripped: {now}", register=R.SW, drive=st.device_id, drive_name=st.name
    )


def emergency_outcome(st: DriveStatus, before: DriveStatus, since: float) -> DriveFaultError:
    """What `st` shows, read `since` s after it took the emergency stop (OFF3) let through while its
    watchdog was starved (`before`: its read before that ramp): at standstill (stopped by the OFF3),
    or tripped, as the failure (it ran on through the ramp stop before)."""
    read = f"read {since:.1f} s after it took the emergency stop let through to it: ACT {fmt_speed(st.actual)}"
    if st.tripped:
        return DriveFaultError(
            f"{read} (was {fmt_speed(before.actual)}), tripped, {'at standstill' if st.stopped else 'turning'}",
            register=R.FAULT,
            fault_code=st.fault_code,
            drive=st.device_id,
            drive_name=st.name,
        )
    return DriveFaultError(
        f"{read}, {st.state}: stopped by its emergency ramp (it had run on through the ramp stop)",
        register=R.SW,
        drive=st.device_id,
        drive_name=st.name,
    )
