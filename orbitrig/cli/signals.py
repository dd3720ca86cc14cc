"""Signals that end a command which moves the drives: SIGINT (Ctrl-C), SIGTERM (a service
manager, a shutdown), SIGHUP (a closed terminal) and SIGQUIT (Ctrl-\\, handled as SIGTERM: no
core dump while the drives turn; before a command handles it, from the command line's start on,
orbitrig.__main__ ends the process on it as SIGTERM would then: exit 131, no core dump). What such
a command prints goes through orbitrig.cli.terminal, which a reader gone away does not end either.

:func:`run_until_signal` runs a coroutine whose way out stops both drives (an ``async with``
of the rig) and cancels it on the first of these signals, so the drives are stopped on each
of them as on Ctrl-C; the signal comes back as :class:`Interrupted`. Each further signal
cancels it again: a stop under way that is shielded from cancellation (orbitrig.run.safe_stop)
is not cut short, it becomes the emergency stop and still waits for standstill; anything else
the way out waits for (a prompt, a read) ends at once, so a second Ctrl-C is never lost.

A signal the process was started with ignored (inherited SIG_IGN: ``nohup`` ignores SIGHUP; a
background job of a shell without job control, ``orbitrig sweep ... &`` in a script, SIGINT and
SIGQUIT) stays ignored, as Unix programs leave it (:func:`watched`): a sweep started under
``nohup`` goes on when its terminal closes; SIGTERM, the service's stop and the dashboard still
stop it.

Once a command's event loop is done with them (:func:`hand_over`), a signal no longer falls to
Python's default (a KeyboardInterrupt traceback, or death by SIGTERM, in the middle of the way
out): it is recorded until the process exits (:func:`take_late_signals`; the third in a row falls
to Python's default, so that a process held at its exit can be interrupted). The command then acts on it
where the drives are not left stopped (`drives run`, which leaves them at the setpoint: both are
opened again and ramped to zero); elsewhere its way out has already stopped the drives, and it
exits with its own status.

Ctrl-Z (SIGTSTP) does not suspend a command that commands the drives (:func:`refuse_suspension`):
a suspended process would leave them turning unwatched (no interlock read, no signal acted on,
no abort taken) until their comm-loss watchdog trips them, a fault rather than a stop. The
command says so and goes on; from its loop's end (`hand_over`) to the process's exit the key is
ignored. SIGSTOP cannot be refused: the drives' watchdog ([drives] comm_loss_timeout_s) then
trips them, and on SIGCONT the command finds the trip and ends as on any drive fault.

For the same reason such a command ignores SIGTTIN and SIGTTOU (`refuse_suspension`, up to the
process's exit), with which the kernel stops a background job of its terminal (``orbitrig sweep
... &``, or ``bg``) that reads the terminal (an operator's prompt) or, after ``stty tostop``,
writes on it: its writes go through, and a read fails (EIO) instead. The prompt's reader
(orbitrig.cli.terminal.terminal_line) takes that for a prompt nobody can answer there, as
without a terminal (the sweep's pause or confirmation stops the run after [interlocks]
unanswered_pause_s; the calibration's prompt with the drives turning fails the step after it),
says so once and reads again once the job is brought to the foreground (``fg``; the wait then
no longer stops the run nor fails the step: its limit is lifted, orbitrig.run.unanswered).
"""

from __future__ import annotations

import logging
import signal
from collections.abc import Awaitable, Callable
from typing import TypeVar

T = TypeVar("T")

SIGNALS: tuple[signal.Signals, ...] = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT)
#: how an operator gives each of SIGNALS
_SENT_AS = {signal.SIGINT: "Ctrl-C", signal.SIGTERM: "SIGTERM", signal.SIGHUP: "SIGHUP", signal.SIGQUIT: "SIGQUIT"}


#: the terminal's suspend key, Ctrl-Z: refused while a command commands the drives
SUSPEND = signal.SIGTSTP

#: SIGNALS and SUSPEND ignored when this process started (read when this module is first imported,
#: before any command handles a signal): they are left ignored (SUSPEND with nothing said)
IGNORED_AT_START: frozenset[signal.Signals] = frozenset(
    s for s in (*SIGNALS, SUSPEND) if signal.getsignal(s) is signal.SIG_IGN
)


def watched(signals: tuple[signal.Signals, ...] = SIGNALS) -> tuple[signal.Signals, ...]:
    """`signals` less those ignored when the process started (IGNORED_AT_START): the ones a
    command handles."""
    return tuple(sig for sig in signals if sig not in IGNORED_AT_START)


def signal_words() -> str:
    """The signals this process acts on (`watched`) in words, as the operator gives them: 'Ctrl-C,
    SIGTERM, SIGHUP or SIGQUIT', without Ctrl-C in a background job of a script (SIGINT ignored)."""
    names = [_SENT_AS[sig] for sig in watched()]
    if not names:
        return "no signal (all ignored since its start)"
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} or {names[-1]}"


def ignored_words() -> str | None:
    """What the process ignores since its start, for the run's log and the operator ('SIGHUP
    (closing the terminal does not stop it)'), or None."""
    names = ", ".join(sig.name for sig in SIGNALS if sig in IGNORED_AT_START)
    if not names:
        return None
    hup = " (closing the terminal does not stop it)" if signal.SIGHUP in IGNORED_AT_START else ""
    return f"started with {names} ignored (nohup, or a background job): left ignored{hup}"


def log_ignored(command: str) -> None:
    """Log (a warning of logger ``orbitrig.cli.<command>``) what the process ignores since its
    start (`ignored_words`), if anything: `orbitrig serve` and `orbitrig dashboard` say it at their
    start (a background job of a script: SIGINT ignored, Ctrl-C does not reach it)."""
    if (ignored := ignored_words()) is not None:
        logging.getLogger(f"orbitrig.cli.{command}").warning("%s", ignored)


#: signals received once a command's event loop no longer handled them (`hand_over`), in order
_late: list[signal.Signals] = []


#: what stops a background job of the terminal that reads it (SIGTTIN) or, after `stty tostop`,
#: writes on it (SIGTTOU): ignored while a command commands the drives, as SUSPEND is refused
BACKGROUND_STOPS: tuple[signal.Signals, ...] = (signal.SIGTTIN, signal.SIGTTOU)


#: why a command that moves the drives does not suspend (`suspension_words`)
DRIVES_TURN = "while it commands the drives (they would turn unwatched until their comm-loss watchdog trips them)"


def suspension_words(command: str, why: str = DRIVES_TURN) -> str:
    """What `orbitrig <command>` says on a refused Ctrl-Z (`refuse_suspension`)."""
    return f"Ctrl-Z ignored: orbitrig {command} does not suspend {why}"


def refuse_suspension(loop, command: str, say: Callable[[str], object], why: str = DRIVES_TURN) -> None:
    """Ctrl-Z (SUSPEND) no longer suspends the process: `loop` calls ``say(suspension_words(command,
    why))`` on each instead; `hand_over` leaves it ignored up to the process's exit. A process started
    with it ignored is left so (nothing to say: it does not suspend either); one that refused it before
    (a command run after another: a calibration's next step) says it again. BACKGROUND_STOPS are
    ignored from here to the process's exit: a background job's read of the terminal fails (EIO,
    orbitrig.cli.terminal.terminal_line), its write goes through."""
    for sig in BACKGROUND_STOPS:
        signal.signal(sig, signal.SIG_IGN)
    if SUSPEND not in IGNORED_AT_START:
        loop.add_signal_handler(SUSPEND, say, suspension_words(command, why))


def hand_over(loop) -> None:
    """Remove `loop`'s handlers of SIGNALS; from here to the process's exit each signal is recorded
    (`take_late_signals`) instead of falling to Python's default. None is lost meanwhile: they are
    blocked during the change and delivered after it. Ctrl-Z, if refused (`refuse_suspension`),
    is ignored from here on, as BACKGROUND_STOPS stay: the way out may still be stopping the drives."""
    blocked = signal.pthread_sigmask(signal.SIG_BLOCK, (*SIGNALS, SUSPEND))
    try:
        if loop.remove_signal_handler(SUSPEND):
            signal.signal(SUSPEND, signal.SIG_IGN)
        for sig in watched():
            loop.remove_signal_handler(sig)
            signal.signal(sig, _record)
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, blocked)


#: late signals recorded in a row before the next one ends the process as Python's default would
#: (a process held at its exit, e.g. by a stalled disk, can still be interrupted)
LATE_SIGNALS_KEPT = 2


def _record(sig: int, _frame: object) -> None:
    if len(_late) >= LATE_SIGNALS_KEPT:
        signal.signal(sig, signal.default_int_handler if sig == signal.SIGINT else signal.SIG_DFL)
        signal.raise_signal(sig)
        return
    _late.append(signal.Signals(sig))


def take_late_signals() -> list[signal.Signals]:
    """The signals recorded since a command's loop handed them over (`hand_over`), in order;
    forgotten here (a command about to run takes them to start afresh)."""
    taken = list(_late)
    del _late[: len(taken)]
    return taken


class Interrupted(Exception):
    """The command was cancelled by `sig` (its drives were stopped on the way out)."""

    def __init__(self, sig: signal.Signals):
        super().__init__(signal_name(sig))
        self.sig = sig


def signal_name(sig: int) -> str:
    """'Ctrl-C' for SIGINT, else the signal's name ('SIGTERM')."""
    return "Ctrl-C" if sig == signal.SIGINT else signal.Signals(sig).name


#: what a signal tells of its cause, where it tells something
_CAUSES = {signal.SIGHUP: "the terminal was closed"}


def signal_cause(sig: int) -> str:
    """The signal and what sent it, for the run's records: 'SIGHUP: the terminal was closed',
    'Ctrl-C', 'SIGTERM'."""
    cause = _CAUSES.get(signal.Signals(sig))
    return f"{signal_name(sig)}: {cause}" if cause else signal_name(sig)


#: the words of a signal that came after another (it aborts, or makes a stop the emergency stop)
SECOND = "a second signal"


def second_signal(words: str) -> str:
    """A signal that came after another, as every command says it (run.log, the terminal, the
    service's log): the signal's own `words` first ('SIGTERM', signal_cause's 'SIGHUP: the terminal
    was closed'), then SECOND: 'SIGTERM; a second signal'."""
    return f"{words}; {SECOND}"


def run_until_signal(make: Callable[[], Awaitable[T]], command: str) -> T:
    """``asyncio.run(make())``, cancelled by the first of SIGNALS and again by each further one
    (raises Interrupted, naming the first, after the coroutine's own way out has run); Ctrl-Z is
    refused (`refuse_suspension`: `orbitrig <command>` says so)."""
    import asyncio  # here, not at the top: `orbitrig --help` loads this module

    from orbitrig.cli.terminal import off_the_loop, say_aside

    async def main() -> T:
        task = asyncio.current_task()
        assert task is not None
        loop = asyncio.get_running_loop()
        received: list[signal.Signals] = []

        def on_signal(sig: signal.Signals) -> None:
            received.append(sig)
            task.cancel()  # again on a further signal: what the way out waits for is cut short

        for sig in watched():
            loop.add_signal_handler(sig, on_signal, sig)
        refuse_suspension(loop, command, say_aside)
        try:
            return await make()
        except asyncio.CancelledError:
            if not received:
                raise
            while task.cancelling():
                task.uncancel()
            raise Interrupted(received[0]) from None
        finally:
            hand_over(loop)

    with off_the_loop():  # a terminal that stops reading (Ctrl-S) holds neither the drives' poll nor a signal
        return asyncio.run(main())
