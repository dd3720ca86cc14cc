"""`orbitrig drives stop`, and what the drive commands say reached the drives: the kind of a
failure, whether the stop a failed session sent on its way out was delivered, and which drive
took the stop word that is sent without reading first when the drives cannot be opened."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from orbitrig.run.stop_words import StopWordsSent


def reason(err: BaseException) -> str:
    from drives.errors import (
        DriveExceptionResponse,
        DriveFaultError,
        DriveLimitError,
        DriveLinkError,
        DriveTimeoutError,
    )
    from orbitrig.cli.drives_hold import WatchdogOff
    from orbitrig.cli.terminal import OutputError

    for cls, word in (
        (WatchdogOff, "watchdog"),
        (DriveLimitError, "limit"),
        (DriveFaultError, "fault"),
        (DriveTimeoutError, "timeout"),
        (DriveLinkError, "link"),
        (DriveExceptionResponse, "refused"),
        (OutputError, "output"),
    ):
        if isinstance(err, cls):
            return word
    return "error"


def stop_outcome(rig) -> str:
    """What became of the stop a failed RigDrives session sent on its way out."""
    from drives.opening import watchdog_words

    if rig is None or rig.link.connects == 0:
        return "nothing sent"
    if (ended := rig.entry.failed_on) is not None and not rig.entry.stop_sent:  # a failed entry's own stop
        return "nothing sent (both drives read at standstill)" if isinstance(ended, Exception) else "nothing sent"
    if rig.stop_errors and (absent := _nothing_started(rig)):
        names = ", ".join(f"{d.name} (id {d.device_id})" for d in absent)
        there = [d for d in (rig.spin, rig.orbit) if d not in absent]
        rest = f"; stop sent to {there[0].name} (id {there[0].device_id})" if there else ""
        return f"no device at {names}: nothing was started there, no stop needed{rest}"
    if rig.stop_errors:
        return f"stop NOT delivered ({rig.stop_errors[0]}); {watchdog_words((rig.spin, rig.orbit))}"
    return "stop sent to both drives"


def _nothing_started(rig) -> list:
    """The drives every failure of the stop is at, if each is a device that is not there (Modbus
    exception 10/11 from the gateway, or no answer at its id while the other drive took the stop)
    and no run word was written to it; else none (the stop was not delivered where it may matter)."""
    from drives.errors import DriveTimeoutError

    drives = {d.device_id: d for d in (rig.spin, rig.orbit)}
    failed = {e.drive for e in rig.stop_errors}
    if not failed <= drives.keys() or any(drives[i].run_sent for i in failed):
        return []
    took_it = len(failed) < len(drives)  # the other drive took the stop: the link itself works
    if all(_gateway_absent(e) or (took_it and isinstance(e, DriveTimeoutError)) for e in rig.stop_errors):
        return [drives[i] for i in failed]
    return []


def _gateway_absent(err: BaseException) -> bool:
    """Whether `err` is a gateway's word that no device has that id (Modbus exception 10 or 11)."""
    from drives.errors import DriveExceptionResponse

    return isinstance(err, DriveExceptionResponse) and err.exception_code in (10, 11)


#: what to check when the drives' link could not be opened
HINT_CONNECT = (
    "is the drives' Modbus server (or `orbitrig sim`) serving there? set [transports] modbus_url in the rig config "
    "or pass --modbus"
)


def failed_line(command: str, err: BaseException, message: str | None = None) -> str:
    """The error line of `drives COMMAND` failed by `err` (its kind as the part: link, limit, ...)
    saying `message` (default: the error itself)."""
    from orbitrig.cli.failure import error_line

    part = reason(err)
    return error_line(str(err) if message is None else message, None if part == "error" else part, f"drives {command}")


#: what to check when a gateway answers that no device has the drive's id (Modbus exceptions 10, 11)
HINT_DEVICE_ID = (
    "is that the drive's device id? set [drives] spin_id and orbit_id in the rig config or pass --spin-id, --orbit-id"
)


def report(command: str, err: BaseException, after: str = "") -> None:
    from drives.errors import DriveConnectError, DriveExceptionResponse
    from orbitrig.run.rig_answers import port_hint
    from orbitrig.cli.terminal import say

    tail = f"; {after}" if after else ""
    hint = f"\n  {port_hint(err) or HINT_CONNECT}" if isinstance(err, DriveConnectError) else ""
    if isinstance(err, DriveExceptionResponse) and err.exception_code in (10, 11):
        hint = f"\n  {HINT_DEVICE_ID}"
    say(failed_line(command, err, f"{err}{tail}{hint}"), err=True)


async def stop_drives(url, d, emergency, timeout, interrupt) -> int:
    """Stop both drives and wait for standstill. Once the drives are open a signal no longer ends the
    command: during a ramp stop it makes it the emergency stop (OFF3), still waited for (`timeout`,
    default the drives' own ramp time with a margin), exit 4; during an emergency stop it is said,
    exit 2. If the drives cannot be opened (a DriveError, or a signal while opening them: nothing
    was sent yet), the stop words still go to each drive that answers (a ramp stop is the emergency
    stop if a drive reads in its emergency ramp first: orbitrig.run.stop_words), and the message
    names those that took it and what the reads first found."""
    import asyncio  # here, not at the top: `orbitrig --help` loads this module

    from drives.errors import DriveError
    from orbitrig.cli.drives_hold import say_drive_states
    from orbitrig.cli.terminal import say
    from orbitrig.run.drive_setup import UNLIMITED, rig_drives
    from orbitrig.run.safe_stop import stop_shielded

    rig, opened = rig_drives(url, d, UNLIMITED), False
    try:
        async with rig:
            opened = True
            interrupt.stopping = True  # from here a signal makes the stop an emergency stop, never cancels it
            escalated, line = await stop_shielded(rig, interrupt.abort, emergency=emergency, timeout=timeout)
            state = rig.state
    except asyncio.CancelledError:
        if not interrupt.received:
            raise
        task = asyncio.current_task()
        assert task is not None
        task.uncancel()
        if opened:  # the rig's exit has sent the stop again: whether both took it
            say(f"orbitrig drives stop: interrupted by {interrupt.received[-1].name}; {stop_outcome(rig)}", err=True)
            return 2
        sent = await stop_words(url, d, interrupt, emergency=emergency)
        by_signal = sent.emergency and not emergency and not sent.by_read  # the emergency stop a signal asked for
        kind = f"; {sent.said(interrupt)}" if by_signal or _read_said(sent) else ""
        first = interrupt.received[0].name
        say(
            f"orbitrig drives stop: interrupted by {first} while opening the drives{kind}; {delivered(sent.took)}",
            err=True,
        )
        return 4 if by_signal else 2
    except DriveError as err:
        # The controller could not be opened (or the wait failed): still put the
        # stop word on the line for each drive that answers (a ramp stop after one status read).
        sent = await stop_words(url, d, interrupt, emergency=emergency)
        read = f"{sent.said(interrupt)}; " if _read_said(sent) else ""
        report(
            "stop",
            err,
            (_signalled(interrupt, escalated=not emergency) if opened else "") + read + delivered(sent.took),
        )
        return 2
    say_drive_states(state)
    if not interrupt.received:
        return 0
    say(f"orbitrig drives stop: {_signalled(interrupt, escalated)}both drives stopped; {line}", err=True)
    return 4 if escalated else 2


def _signalled(interrupt, escalated: bool) -> str:
    """What the signals received once the drives were open did: 'Ctrl-C during the ramp stop:
    emergency stop (OFF3) sent; ', 'SIGTERM during the emergency stop; ', or '' (none)."""
    if not interrupt.received:
        return ""
    names = ", ".join(dict.fromkeys(s.name for s in interrupt.received))
    return f"{names} during the " + ("ramp stop: emergency stop (OFF3) sent; " if escalated else "emergency stop; ")


def _read_said(sent: StopWordsSent) -> bool:
    """Whether the reads before a ramp stop found something to say: a drive in its emergency ramp
    (the emergency stop sent instead), or a drive not read (orbitrig.run.stop_words)."""
    return sent.read is not None and not sent.escalated and bool(sent.read.said())


def delivered(sent: list[str]) -> str:
    """'stop word delivered to: spin (id 1), orbit (id 2)' (or 'no drive')."""
    return f"stop word delivered to: {', '.join(sent) or 'no drive'}"


async def stop_words(url, d, interrupt, *, emergency: bool = False) -> StopWordsSent:
    """The stop words to each drive that answers, over a link of their own
    (orbitrig.run.stop_words): the emergency stop (OFF3) if `emergency` or a signal has asked for
    it (`interrupt.abort`), nothing read first; else the ramp stop (OFF1) after one status read of
    each drive (the emergency stop if one reads in its emergency ramp), made OFF3 by a signal
    meanwhile; a signal never cuts them short (`stopping`)."""
    from orbitrig.run.stop_words import send_stop_words

    interrupt.stopping = True
    return await send_stop_words(url, d, emergency=emergency, escalate=interrupt.abort)
