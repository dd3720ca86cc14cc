"""Errors of the drive layer.

    DriveError(message, *, drive, register, fault_code)
    +-- DriveFaultError        a drive tripped (fault_code set) or refused to start
    |   +-- StopTripError      a drive tripped while both were being stopped
    +-- DriveLimitError        a command outside the configured limits (nothing sent)
    +-- DriveLinkError         the Modbus link is down or answers garbage
    |   +-- DriveConnectError  the link could not be opened: nothing answered at its address
    |   +-- DriveLinkDropped   a request's connection broke (reset, line error, garbage answer): dropped
    +-- DriveTimeoutError      no answer in time, or a state not reached in time
    +-- DriveExceptionResponse the drive answered a Modbus exception (exception_code)
    +-- DriveSuperseded        a request of a command not sent: a stop was asked after the command
    +-- DriveGaveWay           a poll's read given up unanswered: a stop needed the link (TCP)

The message names the drive (`spin drive (id 1)`), the register (`REF (1)`),
or the registers of a multi-register request (`registers 105..106
(AT_SETPOINT_BAND .. ?)`: an exception answer does not say which one failed), and
the fault code with its meaning, whichever apply.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, TypedDict

from rigerrors import OrbitrigError

from drives.registers import EXCEPTION_NAMES, FAULT, fault_name, registers_name

#: both drives read at zero speed, in the operator's words (a stop's end, RigDriveState.motion)
STANDSTILL = "both drives at standstill"

if TYPE_CHECKING:
    from drives.drive import DriveStatus


class ErrorContext(TypedDict, total=False):
    """Where a drive error happened: the keyword arguments every DriveError takes."""

    drive: int | None
    drive_name: str | None
    register: int | None
    count: int | None
    fault_code: int | None


class DriveError(OrbitrigError):
    """A drive or its link failed.

    Attributes
    ----------
    drive : int | None
        Modbus device id of the drive concerned.
    drive_name : str | None
        `'spin'` or `'orbit'` when known.
    register : int | None
        Protocol address of the register concerned (the first of a range).
    count : int | None
        Number of registers from `register` a multi-register request covered
        (None or 1: that register alone).
    fault_code : int | None
        The drive's FAULT code (0 = none) when it is part of the story.
    """

    def __init__(
        self,
        message: str,
        *,
        drive: int | None = None,
        register: int | None = None,
        fault_code: int | None = None,
        drive_name: str | None = None,
        count: int | None = None,
    ):
        self.reason = message
        self.drive = drive
        self.drive_name = drive_name
        self.register = register
        self.count = count
        self.fault_code = fault_code
        parts = []
        if drive is not None or drive_name is not None:
            parts.append(self.who)
        if register is not None:
            parts.append(registers_name(register, count or 1))
        if fault_code:
            parts.append(f"fault {fault_code} ({fault_name(fault_code)})")
        super().__init__(f"{', '.join(parts)}: {message}" if parts else message)

    @property
    def who(self) -> str:
        """'orbit drive (id 2)', 'drive (id 2)' or 'orbit drive': the drive as messages name it."""
        who = f"{self.drive_name} drive" if self.drive_name else "drive"
        return f"{who} (id {self.drive})" if self.drive is not None else who


class DriveFaultError(DriveError):
    """A drive is tripped (see `fault_code`) or did not reach the commanded state."""


class StopTripError(DriveFaultError):
    """A drive tripped while both were being stopped: a fault first read after the stop command
    on a drive not known tripped before it. `fault_code`, `drive`: the first drive that tripped;
    `tripped`: the statuses of all that did; `standstill`: both drives read zero speed after it."""

    def __init__(self, tripped: Sequence[DriveStatus], *, stop: str, standstill: bool, end: str):
        first = tripped[0]
        too = "".join(f"; {s.name} drive (id {s.device_id}) tripped too (fault {s.fault_code})" for s in tripped[1:])
        end = STANDSTILL if standstill else end
        super().__init__(
            f"tripped during the {stop}{too}; {end}",
            drive=first.device_id,
            drive_name=first.name,
            register=FAULT,
            fault_code=first.fault_code,
        )
        self.tripped = list(tripped)
        self.standstill = standstill


class DriveLimitError(DriveError, ValueError):
    """A speed command outside the limits; it was refused and nothing was sent."""


class DriveLinkError(DriveError):
    """The Modbus link to the drives is down or broken."""


class DriveConnectError(DriveLinkError):
    """The Modbus link to the drives could not be opened: nothing answered at its address."""


class DriveLinkDropped(DriveLinkError):
    """A request sent failed with its connection: the TCP connection was reset or closed, the RTU
    line failed (OSError), or the answer made no sense. The link dropped the connection, so the
    next request goes out on a new one (a stop's retry may get through: drives/stop.py)."""


class DriveOffCommand(DriveError):
    """A drive running at the commanded speed found no longer running, taken to local control, or
    given another reference: stopped or moved by another Modbus client, or at the drive itself."""


class DriveTimeoutError(DriveError, TimeoutError):
    """No answer in time, or the drives did not reach a state in time."""


class DriveSuperseded(DriveError):
    """A request of a command (a start's words) not sent: a stop was asked after the command was
    given, and nothing of the command may go out after the stop."""


class DriveGaveWay(DriveError):
    """A read of the poll given up before its answer because a stop needed the link (TCP: its
    connection dropped, the stop's words go out on a new one). Tells nothing of the drive or the link."""


class DriveExceptionResponse(DriveError):
    """The drive answered with a Modbus exception response.

    `exception_code`: 1 illegal function, 2 illegal data address, 3 illegal data
    value (e.g. a parameter written while running), 4 device failure.
    """

    def __init__(
        self,
        message: str,
        *,
        exception_code: int,
        drive: int | None = None,
        register: int | None = None,
        fault_code: int | None = None,
        drive_name: str | None = None,
        count: int | None = None,
    ):
        self.exception_code = exception_code
        meaning = EXCEPTION_NAMES.get(exception_code, "unknown exception")
        super().__init__(
            f"{message}: Modbus exception {exception_code:02d} ({meaning})",
            drive=drive,
            register=register,
            fault_code=fault_code,
            drive_name=drive_name,
            count=count,
        )
