"""The operator at the terminal of `orbitrig sweep`: confirmations, Ctrl-C (pause and ask), a second Ctrl-C (abort)."""

from __future__ import annotations


class Operator:
    """Terminal side of the engine: answers confirmations, Ctrl-C pauses and asks, twice aborts."""

    def __init__(self, engine, console):
        import asyncio

        self.engine, self.console = engine, console
        self.loop = asyncio.get_running_loop()
        self.interrupts = 0
        self.lines: asyncio.Queue[str | None] = asyncio.Queue()
        self.reader = None
        self.asking = None
        self.eof = False  # standard input closed: nobody can answer, so the run stops

    def install(self) -> None:
        import signal

        self.loop.add_signal_handler(signal.SIGINT, self._sigint)

    def uninstall(self) -> None:
        import signal

        self.loop.remove_signal_handler(signal.SIGINT)
        if self.asking is not None:
            self.asking.cancel()

    def _start_reader(self) -> None:
        import sys
        import threading

        if self.reader is not None:
            return

        def read():  # a daemon thread: a pending input() never holds the exit
            for line in sys.stdin:
                self.loop.call_soon_threadsafe(self.lines.put_nowait, line.strip())
            self.loop.call_soon_threadsafe(self.lines.put_nowait, None)

        self.reader = threading.Thread(target=read, name="operator-stdin", daemon=True)
        self.reader.start()

    def _sigint(self) -> None:
        self.interrupts += 1
        if self.interrupts >= 2:
            self.console.print("second Ctrl-C: aborting (emergency ramp down)", style="bold red")
            self.engine.request_abort()
            return
        self.engine.request_pause()
        self._ask("paused at the next safe point: [r]esume, [s]top, [a]bort? (Ctrl-C again aborts) ", self._choice)

    def on_event(self, ev) -> None:
        from orbitrig.run.engine import StatusEvent

        if isinstance(ev, StatusEvent) and ev.state == "waiting" and self.engine.waiting_step:
            step = self.engine.waiting_step
            self._ask(f"{ev.message}\npress Enter to confirm {step} (or type stop / abort): ",
                      lambda ans: self._confirm(step, ans))  # fmt: skip

    def _ask(self, prompt: str, handle) -> None:
        import asyncio

        if self.asking is not None:
            self.asking.cancel()
        self._start_reader()
        self.console.print(prompt, style="bold yellow", markup=False)  # a whole line: the live bars redraw over a partial one
        if self.eof:
            self._no_operator()
            return

        async def ask():
            line = await self.lines.get()
            if line is None:
                self.eof = True
                self._no_operator()
            else:
                handle(line)

        self.asking = asyncio.ensure_future(ask())

    def _no_operator(self) -> None:
        self.console.print("\nstandard input is closed, nobody can answer: stopping the run "
                           "(continue later with --resume)", style="bold red", markup=False)  # fmt: skip
        self.engine.request_stop()

    def _choice(self, ans: str) -> None:
        a = ans.lower()[:1]
        if a == "s":
            self.engine.request_stop()
        elif a == "a":
            self.engine.request_abort()
        else:
            self.interrupts = 0
            self.engine.request_resume()

    def _confirm(self, step: str, ans: str) -> None:
        a = ans.lower()
        if a.startswith("abort"):
            self.engine.request_abort()
        elif a.startswith("stop"):
            self.engine.request_stop()
        else:
            try:
                self.engine.confirm(step)
            except Exception as err:  # noqa: BLE001 - tell the operator, keep going
                self.console.print(f"not confirmed: {err}", markup=False)
