"""The operator's answers at the terminal of `orbitrig calibrate` on the rig: standard input's
lines, one reader at a time (`StandardInput`), and a prompt's Enter (`confirmed`)."""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import sys
import threading
from collections.abc import Callable
from typing import TextIO

from orbitrig.cli.terminal import background_words, say, say_aside, terminal_line
from orbitrig.run.calibration import CalibrationFailed
from orbitrig.run.room_check import on_daemon_thread


class StandardInput:
    """Standard input's lines for the operator's prompts, read on one daemon thread at a time (a
    pending read never holds the exit; asyncio's own worker threads would, until someone pressed
    Enter). A prompt cancelled while its read waits (Ctrl-C, SIGTERM) leaves that read to the
    next prompt, which gets the next line: no second reader races the first for standard input,
    which would take the first Enter for a prompt nobody waits for any more. A line read while
    no prompt waits answered a prompt that was cancelled: it is dropped. A background job's read
    (orbitrig.cli.terminal.terminal_line) says once that the prompt waits for `fg` (`meanwhile`: what
    becomes of it there) and reads again in the foreground."""

    def __init__(self, stream: Callable[[], TextIO] = lambda: sys.stdin):
        self.stream = stream
        self.meanwhile = "the step waits"  # what becomes of the prompt while nobody can answer it
        self._lock = threading.Lock()
        self._read: concurrent.futures.Future[str] | None = None

    def next_line(self) -> concurrent.futures.Future[str]:
        """The read under way, or a new one: its result the line, EOFError at the end of the input."""
        with self._lock:  # held until the new read is recorded: its end, which forgets it, waits for that
            if self._read is None:
                self._read = on_daemon_thread(self._readline, "calibrate-stdin")
            return self._read

    async def line(self) -> str:
        """The next line (EOFError at the end of the input); a cancellation leaves the read under
        way to the next call."""
        loop = asyncio.get_running_loop()
        answered: asyncio.Future[str] = loop.create_future()

        def settle(read: concurrent.futures.Future[str]) -> None:
            if answered.done():
                return
            err = read.exception()
            answered.set_result(read.result()) if err is None else answered.set_exception(err)

        def on_read(read: concurrent.futures.Future[str]) -> None:
            with contextlib.suppress(RuntimeError):  # the loop is closed: nobody waits
                loop.call_soon_threadsafe(settle, read)

        self.next_line().add_done_callback(on_read)
        return await answered

    def _readline(self) -> str:
        """One line (a closed terminal's error raised: the prompt fails with it), the read forgotten
        once it ended: the next prompt starts another."""
        try:
            text = terminal_line(self.stream(), self._background)
        finally:
            with self._lock:
                self._read = None
        if not text:
            raise EOFError("standard input is closed")
        return text

    def _background(self, waiting: bool) -> None:
        if waiting:  # on a line of its own: the prompt waits at the end of its line
            say_aside("\n" + background_words("calibrate", self.meanwhile))


STDIN = StandardInput()


async def confirmed(prompt: str, meanwhile: str = "the step waits") -> None:
    """The operator's Enter at the terminal (STDIN); CalibrationFailed if standard input is closed.
    `meanwhile`: what becomes of the prompt while nobody can answer it (a background job)."""
    STDIN.meanwhile = meanwhile
    say(f"{prompt}: ", nl=False)
    try:
        await STDIN.line()
    except BaseException as err:  # a cancellation among them: what follows starts on a line of its own
        with contextlib.suppress(OSError):  # an OutputError among them: the step is ending anyway
            say()
        if isinstance(err, (EOFError, OSError)):
            raise CalibrationFailed(f"{err}: nobody can confirm at the terminal") from None
        raise
