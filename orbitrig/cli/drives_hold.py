"""`orbitrig drives run`: the hold (`--hold`), the way out of the run, and the drive status lines
of `orbitrig drives`.

Every way out of `run` but the release at the setpoint ramps both drives to zero and waits
until both are confirmed at standstill before anything says they stopped (`ramp_down`); a
signal during that ramp makes it the emergency stop (OFF3). Output goes through
`orbitrig.cli.terminal.say`: a reader gone away (`| head -1`, a closed terminal) never ends the
command, so a hold goes on until a signal (or another client) ends it; output that cannot be
written (a full disk) ends it as a failure does.
"""

from __future__ import annotations

import asyncio
import signal
import time

from drives.errors import DriveError, DriveOffCommand
from drives.waits import first_set
from orbitrig.cli.failure import error_line
from orbitrig.cli.signals import ignored_words, second_signal, signal_words
from orbitrig.cli.terminal import OutputError, say, say_aside
from orbitrig.run.interlocks import Trip
from orbitrig.run.safe_stop import not_confirmed, stop_shielded


class Interrupt:
    """Signals (orbitrig.cli.signals.SIGNALS) received by a command (`received`: those before it,
    e.g. a late one that a new stop follows). The first one cancels the
    command; while `holding` it ends the hold (`event`) instead. Any further one, and any once
    the ramp stop of the way out has begun (`stopping`, never cleared: the stop words repeated on
    the rig's exit are not cut short either), makes that stop an emergency stop (`abort`).
    `released`: `run` left both drives running at the setpoint; `unsaid`: output that then could
    not be written (a full disk), which fails the command: `run` stops them after all.
    `interlock`: the rig's interlock that failed (drives_watch) and ended the command as a first
    signal would, its stop the emergency stop (OFF3)."""

    def __init__(self, received: list[signal.Signals] | None = None) -> None:
        self.received: list[signal.Signals] = list(received or [])
        self.released = False
        self.unsaid: OutputError | None = None
        self.interlock: Trip | None = None
        self.holding = False
        self.stopping = False
        self.event = asyncio.Event()
        self.abort = asyncio.Event()

    def on_signal(self, sig: signal.Signals, task: asyncio.Task) -> None:
        self.received.append(sig)
        if self.holding:
            self.holding = False
            self.event.set()
        elif self.stopping or len(self.received) > 1:  # a stop is (about to be) under way
            self.abort.set()
        else:
            task.cancel()  # the way out stops both drives

    def escalated_by(self) -> str:
        """The signal that made the stop the emergency stop ('SIGTERM'; after another: 'SIGQUIT; a
        second signal', orbitrig.cli.signals.second_signal)."""
        last = self.received[-1].name
        return second_signal(last) if len(self.received) > 1 else last

    def on_interlock(self, trip: Trip, task: asyncio.Task) -> None:
        """An interlock failed: the command ends as by a first signal, unless a signal or a stop
        came first or the drives were left at the setpoint (the command is ending anyway)."""
        if self.released or self.stopping or self.received or self.interlock is not None:
            return
        self.interlock = trip
        if self.holding:
            self.holding = False
            self.event.set()
        else:
            task.cancel()


class WatchdogOff(DriveError):
    """A drive's COMM_LOSS_TIMEOUT reads 0 (its comm-loss watchdog disabled): nothing would stop it once
    no client polls it, so `run` does not leave it running."""


def armed_watchdog(rig, wanted: float) -> dict[str, float]:
    """Each drive's comm-loss timeout (s) as its parameters read back (`rig.spin.params`,
    `rig.orbit.params`: read on entry, after the configured `wanted` s was written, or read again);
    raises WatchdogOff naming the first drive and the register if one reads 0 (or was not read)."""
    from drives.registers import COMM_LOSS_TIMEOUT, TIME_UNIT

    armed = {}
    for drive in (rig.spin, rig.orbit):
        held = drive.params.comm_loss_timeout if drive.params is not None else 0.0
        if not held > 0:
            raise WatchdogOff(
                f"reads 0, its comm-loss watchdog disabled ([drives] comm_loss_timeout_s = {wanted:g} s asked, "
                f"in units of {TIME_UNIT:g} s): nothing would stop this drive once no client polls it",
                drive=drive.device_id,
                drive_name=drive.name,
                register=COMM_LOSS_TIMEOUT,
            )
        armed[drive.name] = held
    return armed


def drive_line(d: dict) -> str:
    """One drive's status as the terminal says it, from its ``DriveState.to_dict()``: state, at
    setpoint, reference and actual speed (rpm), torque (% of rated), fault, control and status words."""
    flags = ", at setpoint" if d["at_setpoint"] else ""
    return (
        f"{d['state']}{flags}; REF {d['reference_rpm']:.1f} rpm, ACT {d['actual_rpm']:.1f} rpm, "
        f"torque {d['torque_pct']:.1f} %, fault {d['fault_code']} ({d['fault']}), "
        f"CW {d['control_word']}, SW {d['status_word']}"
    )


def say_drive_states(state) -> None:
    """Say both drives' status lines (spin, then orbit: name, Modbus id, `drive_line`) on the terminal."""
    for s in (state.spin, state.orbit):
        say(f"{s.name:5s} (id {s.device_id}): {drive_line(s.to_dict())}")


def _hold_line(state, held: float) -> str:
    parts = []
    for s in (state.spin, state.orbit):
        if s is not None:
            d = s.to_dict()
            flag = "at setpoint" if d["at_setpoint"] else d["state"]
            parts.append(f"{s.name} {d['actual_rpm']:.1f} rpm ({flag})")
    link = "link ok" if state.link_ok else f"LINK DOWN ({state.link_error})"
    return f"holding {held:.0f} s: {', '.join(parts)}; {link}, polls {state.polls}, poll failures {state.poll_failures}"


async def ramp_down(rig, interrupt: Interrupt) -> tuple[bool, str]:
    """Both drives ramped to zero (OFF1; the emergency stop, OFF3, after an interlock) and confirmed
    at standstill, not cut short by a cancellation; a signal meanwhile makes it the emergency stop.
    (escalated, what the drives did); raises what kept the standstill from being confirmed (DriveError)."""
    interrupt.holding, interrupt.stopping = False, True
    return await stop_shielded(rig, interrupt.abort, emergency=interrupt.interlock is not None, timeout=None)


async def way_out(rig, err: BaseException, interrupt: Interrupt, reason) -> int:
    """`run` ended by `err` before its release (a signal's cancellation, a drive failure, output
    that cannot be written, any other exception): both drives stopped first (`ramp_down`), then
    the message. Exit 2 (4: a second signal made it an emergency stop), 1 if the standstill is not
    confirmed; an exception that is neither a signal, a DriveError nor an OutputError is raised
    again after the stop."""
    signalled = isinstance(err, asyncio.CancelledError) and bool(interrupt.received or interrupt.interlock)
    if signalled:
        task = asyncio.current_task()
        assert task is not None
        task.uncancel()
        trip = interrupt.interlock
        head = (
            error_line(trip.message, "interlock", "drives run")
            if trip is not None
            else f"orbitrig drives run: interrupted by {interrupt.received[0].name}"
        )
    elif isinstance(err, (DriveError, OutputError)):
        kind = reason(err)
        head = error_line(str(err), None if kind == "error" else kind, "drives run")
    else:
        head = error_line(type(err).__name__, command="drives run")
    try:
        escalated, line = await ramp_down(rig, interrupt)
    except Exception as stop_err:  # noqa: BLE001 - whatever it was, the drives are not known stopped
        say_aside(f"{head}; {not_confirmed(stop_err)}")
        code = 1
    else:
        again = f"; {interrupt.escalated_by()} during the stop: " if escalated else "; "
        say_aside(f"{head}; both drives stopped{again}{line}")
        code = 4 if escalated else 2
    if not signalled and not isinstance(err, (DriveError, OutputError)):
        raise err
    return code


async def stop_after_release(url, d, interrupt: Interrupt, err: DriveError | OutputError | None = None) -> int:
    """`run` cancelled by a signal as its rig's exit left both drives at the setpoint (after the
    release), signalled once its event loop had ended (orbitrig.cli.signals.take_late_signals),
    or (`err`) failed by what the poll found as the exit left them (the exit stopped them again)
    or by output that could not be written then (a full disk behind standard error):
    whatever that exit sent, both drives are opened again, ramped to zero and confirmed
    at standstill (`ramp_down`; a further signal: the emergency stop, exit 4), exit 2; exit 1 if
    the standstill is not confirmed; if the drives cannot be opened, the stop words still go to
    each drive that answers, and the message names those that took them."""
    from orbitrig.cli.drives_stop import delivered, failed_line, stop_words
    from orbitrig.run.drive_setup import UNLIMITED, rig_drives

    task = asyncio.current_task()
    assert task is not None
    task.uncancel()
    interrupt.stopping = True  # a further signal (also while opening): the emergency stop
    if err is None:
        head = (
            f"orbitrig drives run: interrupted by {interrupt.received[0].name} as it left both drives at the setpoint"
        )
    else:
        head = failed_line("run", err, f"as it left both drives at the setpoint: {err}")
    opened = False
    try:
        async with rig_drives(url, d, UNLIMITED) as rig:
            opened = True
            escalated, line = await ramp_down(rig, interrupt)
    except DriveError as stop_err:
        sent = "" if opened else "; " + delivered((await stop_words(url, d, interrupt)).took)
        say_aside(f"{head}; {not_confirmed(stop_err)}{sent}")
        return 1
    again = f"; {interrupt.escalated_by()} during the stop: " if escalated else "; "
    say_aside(f"{head}; both drives stopped{again}{line}")
    return 4 if escalated else 2


async def stop_after_entry(url, d, interrupt: Interrupt) -> int:
    """`run` cancelled by a signal while it opened the drives (its rig's entry lets go of the link
    at once, drives/entry.py): drives found turning there, or not read yet, would run on until their
    own watchdog stopped them, if armed. The ramp stop words (OFF1) go to each drive that answers,
    over a link of their own, after one status read of each (a drive read in its emergency ramp:
    the emergency stop, OFF3, said so); a further signal makes them the emergency stop (OFF3).
    Exit 2 (4: the emergency stop); the message names the drives that took theirs.
    Standstill is not waited for (nothing was commanded: the stop goes out and the command ends)."""
    from orbitrig.cli.drives_stop import delivered, stop_words

    task = asyncio.current_task()
    assert task is not None
    task.uncancel()
    sent = await stop_words(url, d, interrupt)
    first = interrupt.received[0].name
    line = f"interrupted by {first} while opening the drives; {sent.said(interrupt)}; {delivered(sent.took)}"
    say_aside(f"orbitrig drives run: {line}")
    return 4 if sent.emergency else 2


async def hold_at_setpoint(rig, status_every: float, interrupt: Interrupt) -> int:
    """`run --hold`: poll at the setpoint until a signal (exit 0), until another client stops or
    moves a drive or an interlock fails (drives_watch: the emergency stop; exit 2); each ends with
    both drives stopped and confirmed at standstill (not confirmed: exit 1). A second signal during
    that ramp makes it an emergency stop (exit 4). A fault or a lost link found while holding is
    raised (the way out stops the drives)."""
    if (ignored := ignored_words()) is not None:  # a background job of a script: Ctrl-C does not reach it
        say(f"note: {ignored}", err=True)
    say(f"holding at the setpoint; {signal_words()} ramps both drives to zero (a second one: emergency stop)", err=True)
    interrupt.holding = True
    t0 = time.monotonic()
    elsewhere = await _poll_at_setpoint(rig, status_every, interrupt, t0)
    held = time.monotonic() - t0
    ended_by = None if elsewhere is None else "another client"
    if elsewhere is not None:
        say(
            f"orbitrig drives run: after {held:.0f} s at the setpoint: {elsewhere}; ramping both drives to zero",
            err=True,
        )
    elif (trip := interrupt.interlock) is not None:
        ended_by = "an interlock"
        line = f"after {held:.0f} s at the setpoint: {trip.message}; emergency stop of both drives (OFF3)"
        say(error_line(line, "interlock", "drives run"), err=True)
    else:
        say(f"{interrupt.received[-1].name}: ramping both drives to zero", err=True)
    try:
        escalated, line = await ramp_down(rig, interrupt)
    except DriveError as err:
        say(error_line(f"after {held:.0f} s at the setpoint: {not_confirmed(err)}", command="drives run"), err=True)
        return 1
    say_drive_states(rig.state)
    ramp = time.monotonic() - t0 - held
    say(
        f"held the setpoint for {held:.0f} s; both drives stopped (standstill {ramp:.1f} s later)"
        + (f"; the hold was ended by {ended_by}" if ended_by else "")
    )
    if escalated:
        say(f"{interrupt.escalated_by()} during the ramp: {line}", err=True)
        return 4
    return 2 if ended_by else 0


async def _poll_at_setpoint(rig, status_every: float, interrupt: Interrupt, t0: float) -> str | None:
    """Hold until a signal (None) or another client stops or moves a drive (which one, said: the
    poll found it and is stopping both, drives/poll.py)."""
    last = t0
    while not interrupt.event.is_set():
        await first_set(interrupt.event, timeout=rig.poll_interval)  # a cancel meanwhile always gets through
        try:
            state = rig.check().require_link()  # a trip found by the poll (both already stopping), a lost link
        except DriveOffCommand as err:
            return str(err)
        now = time.monotonic()
        if now - last >= status_every and not interrupt.event.is_set():
            last = now
            say(_hold_line(state, now - t0))
    return None
