"""The drives' stop at the end of a run: a ramp that an abort turns into an emergency stop.

The engine's one `finally` stops both drives first. A ramp stop (completed or
stopped runs, OFF1 along the drives' DECEL_TIME) is watched: an abort that
arrives while it is under way (a second Ctrl-C, a signal, an MQTT abort) sends
the emergency stop (OFF3) at once, taking over the ramp stop's words not yet out
(drives/stop.py), and the run ends aborted (its message 'all points completed; ...' if
every point is complete: orbitrig.run.ending). The line this
returns says what the drives were commanded and how they ended, for run.log.
A stop that is not delivered, or not confirmed at standstill in time, makes the
run failed whatever it was (`unconfirmed`): nobody may take the rig for stopped.
A drive that trips during the run's closing stop (`closing_stop`; RigDrives.stop raises
StopTripError, a trip known before the stop is not reported again) makes a completed or
stopped run failed once both drives are at standstill ('drive tripped during the closing
stop (fault 2310, standstill confirmed)'); an aborted or failed run keeps its status,
the trip added to its message, and so does a run aborted or cancelled during that stop: a
completed or stopped run ends aborted then ('run cancelled while stopping (stopped by ada; drive
tripped during the closing stop ...)'), as an abort during it makes it (RunEngine).

The run's closing stop is not cut short by a cancellation of the run (a fault elsewhere in the
service ends its task group, the service's bounded wait for the run runs out): it counts as an
abort (the ramp becomes the emergency stop, still waited for), and the run ends aborted once both
drives are confirmed at standstill.

`stop_shielded` is the same stop for a command whose way out is a cancellation (a signal
cancels its task): the stop is not cut short by the cancellation, which counts as an abort
(the emergency stop, still waited for) and is raised again once the stop is confirmed.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable

from drives.rig import RigDrives, StopTripError
from drives.waits import done_or_set
from orbitrig.run.ending import while_stopping
from orbitrig.run.states import ABORTED, COMPLETED, FAILED, Outcome


async def stop_drives(
    drives: RigDrives, aborted: asyncio.Event, *, emergency: bool, timeout: float | None
) -> tuple[bool, str]:
    """Stop both drives (`timeout` wall s to standstill, None: the drives' own ramp time with a
    margin); (escalated to an emergency stop, log line)."""
    t0 = time.monotonic()
    escalated = False
    if emergency or aborted.is_set():
        escalated = not emergency
        await drives.stop(emergency=True, wait=True, timeout=timeout)
    else:
        ramp = asyncio.ensure_future(drives.stop(emergency=False, wait=True, timeout=timeout))
        if await done_or_set(ramp, aborted) is ramp:
            ramp.result()
        else:
            drives.stop_now(emergency=True)  # takes over the ramp stop's words still to go out
            ramp.cancel()
            await asyncio.gather(ramp, return_exceptions=True)
            escalated = True
            await drives.stop(emergency=True, wait=True, timeout=timeout)
    again = f" ({drives.stop_again})" if drives.stop_again else ""  # a word not taken at once (drives/stop_again.py)
    return escalated, (  # the words sent (after an emergency stop, every stop is one: drives/owed.py)
        f"drives: {drives.stop_sent}{' after an abort during the ramp' if escalated else ''}{again}; "
        f"standstill after {time.monotonic() - t0:.1f} s: {_speeds(drives)}"
    )


async def stop_shielded(
    drives: RigDrives, aborted: asyncio.Event, *, emergency: bool, timeout: float | None
) -> tuple[bool, str]:
    """`stop_drives`, shielded from the caller's cancellation: a cancellation meanwhile sets
    `aborted` (the ramp becomes the emergency stop) and is raised again once both drives are
    confirmed at standstill; what kept the standstill from being confirmed is raised instead."""
    ended, cancelled = await _stop_through(drives, aborted, emergency=emergency, timeout=timeout)
    if isinstance(ended, BaseException):
        raise ended
    if cancelled:
        raise asyncio.CancelledError
    return ended


async def _stop_through(
    drives: RigDrives, aborted: asyncio.Event, *, emergency: bool, timeout: float | None
) -> tuple[tuple[bool, str] | BaseException, bool]:
    """`stop_drives` not cut short by the caller's cancellation, which sets `aborted` (the ramp
    becomes the emergency stop): ((escalated, log line), or what kept the standstill from being
    confirmed; whether the caller was cancelled meanwhile). A cancellation of the stop itself is raised."""
    stopping = asyncio.ensure_future(stop_drives(drives, aborted, emergency=emergency, timeout=timeout))
    cancelled = False
    while True:
        try:
            return await asyncio.shield(stopping), cancelled
        except asyncio.CancelledError:
            if stopping.cancelled():
                raise
            cancelled = True  # the stop goes on (its own failure wins over the cancellation)
            aborted.set()
        except Exception as err:  # noqa: BLE001 - the caller says what kept the standstill from being confirmed
            return err, cancelled


async def closing_stop(
    drives: RigDrives,
    aborted: asyncio.Event,
    ending: tuple[Outcome, str],
    timeout: float | None,
    note: Callable[[str], None],
    failed: Callable[[str, BaseException], None],
) -> tuple[Outcome, str, bool]:
    """The run's last stop (RunEngine's cleanup): `stop_drives`, the emergency stop if the run is
    `ending` (status, message) aborted or failed; `note` gets the log line, `failed` a stop that
    raised. A cancellation of the run meanwhile does not cut it short: it is an abort (the ramp
    becomes the emergency stop, still waited for; `_cancelled_in_stop`). Returns the run's (status,
    message): failed if the stop was not confirmed (`unconfirmed`) or a drive tripped during it
    (`tripped_in_closing_stop`), aborted if the run was cancelled meanwhile, a trip or not (the trip
    added, as after an abort); and whether both drives were confirmed at standstill (the log line
    noted)."""
    status, message = ending
    try:
        ended, cancelled = await _stop_through(drives, aborted, emergency=status in (ABORTED, FAILED), timeout=timeout)
    except BaseException as err:  # noqa: BLE001 - every cleanup step must run
        ended, cancelled = err, False
    if isinstance(ended, StopTripError) and ended.standstill:
        note(f"drives: {ended}; {_speeds(drives)}")
        status, message = tripped_in_closing_stop(status, message, ended, aborted.is_set())
    elif isinstance(ended, BaseException):
        failed("stop both drives", ended)
        return (*unconfirmed(status, message, ended), False)
    else:
        note(ended[1])
    return (*(_cancelled_in_stop(status, message) if cancelled else (status, message)), True)


def _cancelled_in_stop(status: Outcome, message: str) -> tuple[Outcome, str]:
    """The run's (status, message) when it was cancelled during its closing stop, both drives
    confirmed at standstill: a completed or stopped run aborted (a cancellation is an abort, as
    before the closing stop), saying how it was ending (`while_stopping`); an aborted or failed
    one keeps its own."""
    if status in (ABORTED, FAILED):
        return status, message
    return ABORTED, while_stopping("run cancelled", status, message)


def tripped_in_closing_stop(status: Outcome, message: str, err: StopTripError, aborting: bool) -> tuple[Outcome, str]:
    """The run's (status, message) when a drive tripped during its closing stop, both drives at
    standstill: a completed or stopped run failed, saying so first and how it was ending; an
    aborted run (`aborting`: an abort arrived) or a failed one keeps its status, the trip added
    (a completed one the abort ends next: the trip alone, `while_stopping` says the rest)."""
    trip = tripped_words(err, "closing stop")
    if aborting and status == COMPLETED:  # aborted next, said by `while_stopping`: the trip, no completed run's words
        return status, trip
    if aborting or status in (ABORTED, FAILED):
        return status, f"{message}; {trip}"
    return FAILED, f"{trip} (the run was ending {status}: {message})"


def tripped_words(err: StopTripError, stop: str) -> str:
    """'drive tripped during the closing stop (fault 2310, standstill confirmed): <err>'."""
    codes = ", ".join(str(s.fault_code) for s in err.tripped)
    confirmed = "standstill confirmed" if err.standstill else "standstill not confirmed"
    return f"drive tripped during the {stop} (fault{'s' if len(err.tripped) > 1 else ''} {codes}, {confirmed}): {err}"


def not_confirmed(err: BaseException) -> str:
    """What to say when stopping the drives raised `err` (not delivered, not at standstill in
    time, cancelled): nobody may take the rig for stopped. A drive that tripped during the stop
    with both at standstill (StopTripError) is said as such."""
    if isinstance(err, StopTripError) and err.standstill:
        return tripped_words(err, "stop")
    reason = f"{type(err).__name__}: {err}" if str(err) else type(err).__name__
    return f"drives not confirmed stopped: {reason}"


def unconfirmed(status: Outcome, message: str, err: BaseException) -> tuple[Outcome, str]:
    """The run's (status, message) when stopping the drives raised `err` (not delivered, not at
    standstill in time, cancelled): failed, saying so first and how the run was ending."""
    return FAILED, f"{not_confirmed(err)} (the run was ending {status}: {message})"


def _speeds(drives: RigDrives) -> str:
    st = drives.state
    parts = [
        f"{s.name} ACT {s.to_dict()['actual_rpm']:.0f} rpm, fault {s.fault_code}"
        for s in (st.spin, st.orbit)
        if s is not None
    ]
    return "; ".join(parts) or "no drive state"
