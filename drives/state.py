"""The snapshot of both drives that each poll publishes."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from drives.drive import Drive, DriveStatus
from drives.errors import STANDSTILL, DriveLinkError, DriveOffCommand
from drives import registers as R
from drives.limits import fmt_speed
from rigunits import in_rpm

#: what a lost Modbus link is called wherever it ends something (the run's interlock, a step, a hold)
LINK_LOST = "Modbus link to the drives lost"
#: RigDriveState.motion before both drives were read (the dashboard's page knows these words too)
NOT_READ = "the drives' speeds not read yet"


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

    def at_reference(self, refs: tuple[int, int]) -> bool:
        """Both drives AT_SETPOINT under network control (SW REMOTE) with REF reading the raw
        references `refs` (spin, orbit): a poll that read the drives before those were written
        (AT_SETPOINT of the old ones) does not count, nor a drive at its keypad's speed."""
        if self.spin is None or self.orbit is None or not self.at_setpoint:
            return False
        if not (self.spin.remote and self.orbit.remote):
            return False
        return (self.spin.reference_raw, self.orbit.reference_raw) == tuple(refs)

    def require_link(self) -> RigDriveState:
        """This state, or DriveLinkError if the poll declared the link lost (LINK_LOST, with the
        request that went unanswered)."""
        if not self.link_ok:
            raise DriveLinkError(f"{LINK_LOST} ({self.link_error})")
        return self

    @property
    def stopped(self) -> bool:
        """Both drives read an actual speed of exactly zero."""
        return bool(self.spin and self.orbit and self.spin.stopped and self.orbit.stopped)

    def stopped_of(self, ids: frozenset[int] | None) -> bool:
        """The drives of device `ids` (None: both) read an actual speed of exactly zero."""
        if ids is None:
            return self.stopped
        return all(s.stopped for s in (self.spin, self.orbit) if s is not None and s.device_id in ids)

    def describe(self, since: float | None = None, what: str = "the command") -> str:
        """Each drive's state, reference, actual speed and fault, and a link that is down: for messages.
        With `since` (time.monotonic() of `what`, e.g. "the stop"), a drive not read after it is
        said to be as last read, so a reading from before the stop is never taken for the present."""
        parts = [
            f"{s.name} (id {s.device_id}) {s.state}, REF {fmt_speed(s.reference)}, "
            f"ACT {fmt_speed(s.actual)}, fault {s.fault_code}"
            + (
                ""
                if since is None or s.time > since
                else f" (not read since {what}: as read {since - s.time:.2f} s before it)"
            )
            for s in (self.spin, self.orbit)
            if s is not None
        ]
        if not self.link_ok:
            parts.append(f"link down: {self.link_error}")
        return "; ".join(parts)

    def motion(self) -> str:
        """Whether the spindles turn, for an operator about to put hands on the rig: 'both drives
        at standstill' or the actual speeds."""
        if self.spin is None or self.orbit is None:
            return NOT_READ
        if self.stopped:
            return STANDSTILL
        return f"the drives are turning: {', '.join(f'{s.name} {in_rpm(s.actual):.0f} rpm' for s in (self.spin, self.orbit))}"

    def to_dict(self) -> dict[str, Any]:
        return {
            "link_ok": self.link_ok,
            "link_error": self.link_error,
            "link_losses": self.link_losses,
            "poll_failures": self.poll_failures,
            "spin": self.spin.to_dict() if self.spin else None,
            "orbit": self.orbit.to_dict() if self.orbit else None,
        }


def off_command(
    statuses: Sequence[DriveStatus],
    drives: tuple[Drive, Drive],
    command: tuple[int, int],
    cause: Callable[[DriveStatus], str | None] = lambda st: None,
) -> DriveOffCommand | None:
    """The first drive of `statuses` not running at its raw REF of `command` (spin, orbit) under
    network control: no longer running, taken to local control (its keypad: SW REMOTE = 0), or
    given another reference; `cause(status)`: who did it when known (a late stop word of ours:
    drives/late.stopped_late), else said as likely. None while both run at the command."""
    for st, d, raw in zip(statuses, drives, command):
        if not st.running:
            what, register = f"is no longer running ({st.state}, ACT {fmt_speed(st.actual)})", R.SW
        elif not st.remote:
            what, register = f"was taken to local control (SW REMOTE = 0, ACT {fmt_speed(st.actual)})", R.SW
        elif st.reference_raw != raw:
            what, register = f"was given another reference (REF {fmt_speed(st.reference)})", R.REF
        else:
            continue
        return DriveOffCommand(
            f"{what} while commanded to run at {fmt_speed(d.speed_of(raw))}: {cause(st) or _off_cause(st)}",
            drive=st.device_id,
            drive_name=st.name,
            register=register,
        )
    return None


def _off_cause(st: DriveStatus) -> str:
    """Who likely took the drive off the command: CW and REF reading 0 (no client writes CW 0, a
    stop is OFF1 or OFF3 with REMOTE) are a drive come up from power-on; else another client or
    its keypad."""
    if not st.running and st.control_word == 0 and st.reference_raw == 0:
        return (
            "CW and REF read 0 as after power-on: the drive lost power or was reset "
            "(its parameters are back to their defaults)"
        )
    return "stopped or changed by another client, or at the drive"
