"""The operator at the terminal of `orbitrig sweep`: confirmations, Ctrl-C (pause and ask), signals, aborts.

- Ctrl-C (SIGINT): pause at the next safe point (while a manual setting waits for its
  confirmation: once it is confirmed; the question says which) and ask resume / stop / abort.
  Past the run's last safe point (every point measured: from the last point's identification on,
  through the closing ramp that brings both drives to zero) the run refuses the pause, as it refuses an MQTT pause
  (orbitrig.run.control.NOTHING_TO_PAUSE): the terminal says why and asks stop / abort (emergency
  stop) / Enter (the run completes; so it does when nobody can answer, standard input closed: nothing
  holds it); a second Ctrl-C aborts there too.
- SIGTERM, SIGHUP, SIGQUIT (a service manager, a shutdown, a closed terminal,
  Ctrl-\\): stop at once, both drives ramp to zero (OFF1), the run ends stopped
  (exit 3).
- Ctrl-Z (SIGTSTP): refused, said on the console (orbitrig.cli.signals.refuse_suspension).
- A second signal of any kind, or any signal while a stop is under way or a
  manual setting waits for its confirmation after a Ctrl-C: abort (emergency
  ramp, exit 4; run.log says why: `abort by ada (SIGTERM; a second signal)`).
  Only an explicit "r" at the pause prompt (the run then resumes) makes the
  next Ctrl-C a first one again: a SIGTERM before that answer is read is a
  second signal.
- A stop or an abort asked once every point is complete (the drives ramping down at the end): the drives
  stop as it says and the run ends stopped (exit 3) or aborted (exit 4), as the MQTT contract has it;
  its message starts with 'all points completed; ' (orbitrig.run.ending).
- Standard input not a terminal: nobody can answer a pause, which then stops
  the run after [interlocks] unanswered_pause_s (RunEngine.unattended). So
  while the sweep is a background job of its terminal (`&`, `bg`: its prompt's
  read fails, orbitrig.cli.terminal.terminal_line), said once; brought to the
  foreground (`fg`), the prompt is asked again, the wait no longer limited
  (RunEngine.attended_again), and the terminal answers it.

Each request is recorded as sent by the terminal's operator, with the signal that asked
(`command abort by ada (SIGHUP: the terminal was closed; a second signal)`); the run's end message
says the same.

Once the run has closed the drives (its cleanup done, also when it could not confirm them
stopped: state faulted or stopping while it records its end), any signal aborts; an abort the
run no longer carries out (it does not hold the drives) sends both the emergency stop over a link
of the command's own, as `orbitrig serve` does (orbitrig.service.idle_stop), and prints which
drives took it. A signal while the run waits for a disk that stalls, its drives stopped
(RunEngine.waiting_for_disk: its status says so, one write has not returned for 5 s), leaves the
run if it still waits 2 s later, as `orbitrig serve` leaves one
(orbitrig.service.leaving): the command prints what was not written and exits 1; every file
written before is kept (`--resume` continues it).
"""

from __future__ import annotations

from typing import Any

from orbitrig.cli.signals import (
    hand_over,
    ignored_words,
    refuse_suspension,
    second_signal,
    signal_cause,
    signal_name as _name,
    watched,
)

#: what the terminal asks while the run is paused (a first Ctrl-C, a pause reached)
CHOICES = "[r]esume, [s]top, [a]bort? (Ctrl-C again aborts) "
#: what the terminal asks after a first Ctrl-C the run refused to pause (past its last safe point):
#: a stop ends the run stopped, an abort makes the ramp the emergency stop
CLOSING_CHOICES = "[s]top, [a]bort (emergency stop), Enter: let the run complete? (Ctrl-C again aborts) "


class Operator:
    """Terminal side of the engine: answers confirmations, Ctrl-C pauses and asks, twice aborts."""

    def __init__(self, engine: Any, console: Any) -> None:
        import asyncio
        import threading

        self.engine, self.console = engine, console
        self.loop = asyncio.get_running_loop()
        self.interrupts = 0
        self.lines: asyncio.Queue[str | None] = asyncio.Queue()
        self.reader: Any = None
        self.asking: Any = None
        self.prompt = ""  # the question being asked (asked once while it waits for its answer)
        self.eof = False  # standard input closed: nobody can answer, so the run stops
        self.pending: Any = None  # a signal received before the run started (re-requested at its start)
        self.stopper: Any = None  # the thread sending the emergency stop the run could not send
        self.released = threading.Event()  # the run has ended (uninstall): it holds no drive port
        self.leaving: Any = None  # the task that leaves a run still waiting for its disk (_leave)

    def install(self) -> None:
        import sys

        for sig in watched():
            self.loop.add_signal_handler(sig, self._signal, sig)
        refuse_suspension(self.loop, "sweep", lambda words: self.console.print(words, markup=False))
        if (ignored := ignored_words()) is not None:
            self.console.print(f"note: {ignored}", markup=False)
        if not sys.stdin.isatty():
            self.engine.unattended = True

    def uninstall(self) -> None:
        """The run has ended: signals from here on are recorded only (orbitrig.cli.signals.hand_over);
        the run's way out has closed the drives."""
        self.released.set()
        hand_over(self.loop)
        if self.asking is not None:
            self.asking.cancel()

    def _start_reader(self) -> None:
        import sys
        import threading

        if self.reader is not None:
            return

        from orbitrig.cli.terminal import on_loop, terminal_line

        # each on the loop, none once it closed (a line read after the run's end is dropped)
        heard, background = on_loop(self.loop, self.lines.put_nowait), on_loop(self.loop, self._background)

        def read():  # a daemon thread: a pending read never holds the exit
            try:
                while line := terminal_line(sys.stdin, background):
                    heard(line.strip())
            except OSError:  # a hung-up terminal: nobody can answer, as at the end of the input
                pass
            heard(None)

        self.reader = threading.Thread(target=read, name="operator-stdin", daemon=True)
        self.reader.start()

    def _background(self, waiting: bool) -> None:
        """On the loop (orbitrig.cli.terminal.on_loop): the sweep, a background job of its terminal,
        could not read its prompt's answer (`waiting`): nobody can answer (RunEngine.unattended),
        said once; or it is in the foreground again: the terminal answers, the prompt asked again,
        the wait under way without its limit."""
        if waiting:
            from orbitrig.cli.terminal import background_words

            self.engine.unattended = True
            limit = self.engine.rig.interlocks.unanswered_pause_s
            meanwhile = f"nobody can answer: the run stops after {limit:g} s ([interlocks] unanswered_pause_s)"
            self.console.print(background_words("sweep", meanwhile), style="bold yellow", markup=False)
            return
        self.engine.attended_again()
        if self.asking is not None and not self.asking.done():
            self.console.print(self.prompt, style="bold yellow", markup=False)

    def _signal(self, sig) -> None:
        import signal

        from orbitrig.run.states import IDLE, FAULTED, STOPPING

        self.interrupts += 1
        state = self.engine.state
        if state in (IDLE, FAULTED) and self.engine.run_id is None:  # not started yet: acted upon at the start
            self.pending = sig
            return
        # the request first, then the words: a terminal gone (the hang-up that sent SIGHUP)
        # must not keep the request from the engine. Faulted (or idle) once started: the run has
        # closed the drives and records its end; a signal then aborts, as while stopping.
        if self.interrupts >= 2:  # run.log says why this signal aborts: a second one
            self._abort(second_signal(signal_cause(sig)), second_signal(_name(sig)))
            self._leave_if_stuck(second_signal(_name(sig)))
        elif state == STOPPING:
            self._abort(signal_cause(sig), f"{_name(sig)} while stopping")
            self._leave_if_stuck(f"{_name(sig)} while stopping")
        elif state in (IDLE, FAULTED):
            self._abort(signal_cause(sig), _name(sig))
            self._leave_if_stuck(_name(sig))
        elif sig == signal.SIGINT:
            self._pause(_name(sig))
        else:
            self.engine.request_stop_now(_name(sig))
            self.console.print(
                f"{_name(sig)}: stopping now, both drives ramp to zero (a second signal aborts)",
                style="bold red",
                markup=False,
            )

    def _pause(self, name: str) -> None:
        """A first Ctrl-C: the pause asked and the question (resume / stop / abort); past the run's
        last safe point the run's refusal said (why: nothing left to pause) and stop / abort asked."""
        from orbitrig.run.control import NothingToPause

        try:
            when = self.engine.request_pause()  # 'the run pauses at its next safe point', or once confirmed
        except NothingToPause as refused:
            self._ask(f"{name}: {refused}\n{CLOSING_CHOICES}", self._closing_choice, self._completes)
            return
        # the choices on a line of their own: the terminal's width never splits them
        self._ask(f"pause requested: {when}\n{CHOICES}", self._choice)

    def on_event(self, ev) -> None:
        from orbitrig.run.engine import StatusEvent
        from orbitrig.run.states import RUNNING, WAITING

        if isinstance(ev, StatusEvent) and ev.state == RUNNING and self.pending is not None:
            sig, self.pending = self.pending, None
            self.interrupts -= 1
            self.loop.call_soon(self._signal, sig)
        # a pause asked while waiting is held once the setting is confirmed: its own question is asked
        if (
            isinstance(ev, StatusEvent)
            and ev.state == WAITING
            and self.engine.waiting_step
            and not self.engine.pause_pending
        ):
            self._ask_confirm(ev.message)

    def _ask_confirm(self, message: str) -> None:
        step = self.engine.waiting_step
        self._ask(
            f"{message}\npress Enter to confirm {step} (or type stop / abort): ", lambda ans: self._confirm(step, ans)
        )

    def _ask(self, prompt: str, handle, unanswered=None) -> None:
        """Ask `prompt`, its answer to `handle`; nobody can answer (standard input closed):
        `unanswered` (default: the run stops, `_no_operator`)."""
        import asyncio

        nobody = unanswered or self._no_operator
        if self.asking is not None and not self.asking.done() and prompt == self.prompt:
            return  # asked already (the same wait's status said again)
        if self.asking is not None:
            self.asking.cancel()
        self.prompt = prompt
        self._start_reader()
        self.console.print(
            prompt, style="bold yellow", markup=False
        )  # a whole line: the live bars redraw over a partial one
        if self.eof:
            nobody()
            return

        async def ask():
            line = await self.lines.get()
            if line is None:
                self.eof = True
                nobody()
            else:
                handle(line)

        self.asking = asyncio.ensure_future(ask())

    def _no_operator(self) -> None:
        self.console.print(
            "\nstandard input is closed, nobody can answer: stopping the run (continue later with --resume)",
            style="bold red",
            markup=False,
        )
        self.engine.request_stop(why="standard input closed: nobody can answer")

    def _completes(self) -> None:
        """Nobody can answer the question after a refused pause: nothing holds the run, which completes."""
        self.console.print(
            "\nstandard input is closed, nobody can answer: the run completes (Ctrl-C again aborts)",
            style="bold yellow",
            markup=False,
        )

    def _choice(self, ans: str) -> None:
        a = ans.lower()[:1]
        if a == "s":
            self.engine.request_stop()
        elif a == "a":
            self._abort()
        elif a == "r":
            self.engine.request_resume()
            if self.engine.waiting_step is None:
                self.interrupts = 0
            else:  # still waiting for the confirmation: ask again, the count stays
                self._ask_confirm(self.engine.message)
        else:
            self._ask(CHOICES, self._choice)

    def _closing_choice(self, ans: str) -> None:
        """The answer to a Ctrl-C past the last safe point: stop, abort, anything else lets the run complete."""
        a = ans.lower()[:1]
        if a == "s":
            self.engine.request_stop()
        elif a == "a":
            self._abort()

    def _confirm(self, step: str, ans: str) -> None:
        a = ans.lower()
        if a.startswith("abort"):
            self._abort()
        elif a.startswith("stop"):
            self.engine.request_stop()
        else:
            try:
                self.engine.confirm(step)
            except Exception as err:  # noqa: BLE001 - tell the operator, keep going
                self.console.print(f"not confirmed: {err}", markup=False)

    def _abort(self, why: str = "", head: str | None = None) -> None:
        """Abort the run (`head`: the words that say so, e.g. 'Ctrl-C; a second signal'). If the run no longer
        holds the drives (closed by its cleanup, also when it could not confirm them stopped, or not
        open yet), both get the emergency stop over a link of this command's own, and the outcome
        (which drives took it) is printed."""
        if self.engine.request_abort(why=why):
            if head is not None:
                self.console.print(f"{head}: aborting (emergency ramp down)", style="bold red", markup=False)
            return
        self.console.print(
            f"{head or 'abort'}: the run does not hold the drives (not opened yet, or let go): emergency stop "
            "(OFF3) to both over a link of this command's own",
            style="bold red",
            markup=False,
        )
        if self.stopper is not None and self.stopper.is_alive():
            return  # one under way: its outcome is printed
        import threading

        url, drives = self.engine.access.endpoints.modbus_url, self.engine.rig.drives
        # a thread that is no daemon: the command does not exit before the stop is sent
        self.stopper = threading.Thread(target=self._send_stop, args=(url, drives), name="operator-emergency-stop")
        self.stopper.start()

    def _leave_if_stuck(self, why: str) -> None:
        """After a signal that aborts while the run waits for its disk, its drives stopped (its status
        says so): the command leaves it if it is still waiting LEAVE_GRACE_S later (`_leave`)."""
        import asyncio

        if self.leaving is None and self.engine.waiting_for_disk:
            self.leaving = asyncio.ensure_future(self._leave(why))

    async def _leave(self, why: str) -> None:
        """Once the run is past its drives' closing stop, LEAVE_GRACE_S for it to end; if it has not
        (a disk that does not return), the emergency stop this command sends finished (at most
        SIGNAL_STOP_S), what the run did not write printed, and the process ended (exit 1) without
        joining the thread the disk holds."""
        import asyncio
        import contextlib
        import os

        from orbitrig.service.idle_stop import SIGNAL_STOP_S
        from orbitrig.cli.failure import error_line
        from orbitrig.service.leaving import HOLD_POLL_S, LEAVE_GRACE_S, left_unwritten

        while not self.engine.let_go and not self.released.is_set():
            await asyncio.sleep(HOLD_POLL_S)
        await asyncio.sleep(LEAVE_GRACE_S)
        if self.released.is_set():
            return
        if self.stopper is not None:
            await asyncio.to_thread(self.stopper.join, SIGNAL_STOP_S)
        try:
            with contextlib.suppress(OSError):
                words = left_unwritten(why, self.engine.run_id, self.engine)
                self.console.print(error_line(words, command="sweep"), style="bold red", markup=False)
        finally:
            self.console.written(LEAVE_GRACE_S)  # said, unless the terminal does not read
            os._exit(1)

    def _send_stop(self, url: str, drives: Any) -> None:
        """The emergency stop (orbitrig.service.idle_stop) in this thread's own event loop; its outcome printed."""
        import asyncio

        from orbitrig.service.idle_stop import emergency_stop

        async def send():
            holder = asyncio.ensure_future(_until(self.released))  # a run being opened may hold the port
            try:
                return await emergency_stop(url, drives, holder, own="this command's")
            finally:
                holder.cancel()

        try:
            error, detail = asyncio.run(send())
        except Exception as err:  # noqa: BLE001 - said, never a traceback from this thread
            error, detail = f"emergency stop NOT confirmed sent: {type(err).__name__}: {err}", None
        self.console.print(detail if error is None else error, style="bold red", markup=False)


async def _until(event: Any) -> None:
    """Returns once the threading.Event `event` is set."""
    import asyncio

    while not event.is_set():
        await asyncio.sleep(0.05)
