"""The operator's answers at the terminal of `orbitrig calibrate` on the rig: standard input's
lines, one reader at a time (`StandardInput`), and a prompt's Enter (`confirmed`), within the
limit of a prompt nobody can answer if it has one (the sweep's, orbitrig.run.unanswered)."""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import sys
import threading
import time
from collections.abc import Callable
from typing import TextIO

from orbitrig.cli.terminal import background_words, in_background, on_loop, say, say_aside, terminal_line
from orbitrig.run.calibration_checks import CalibrationFailed
from orbitrig.run.room_check import on_daemon_thread
from orbitrig.run.unanswered import UnansweredWait


class Unanswered(Exception):
    """Nobody could answer a prompt for its limit (`confirmed`)."""


class StandardInput:
    """Standard input's lines for the operator's prompts, read on one daemon thread at a time (a
    pending read never holds the exit; asyncio's own worker threads would, until someone pressed
    Enter). A prompt cancelled while its read waits (Ctrl-C, SIGTERM) leaves that read to the
    next prompt, which gets the next line: no second reader races the first for standard input,
    which would take the first Enter for a prompt nobody waits for any more. A line read while
    no prompt waits answered a prompt that was cancelled: it is dropped. A background job's read
    (orbitrig.cli.terminal.terminal_line) says once that the prompt waits for `fg` (`meanwhile`: what
    becomes of it there) and reads again in the foreground, the prompt waiting asked again; each
    time, ``heard(waiting)`` is called (nobody can answer: True; `fg`: False). Both on the event
    loop of the latest prompt (orbitrig.cli.terminal.on_loop), as the sweep's operator says them:
    the reader's thread neither writes nor touches what the loop owns."""

    def __init__(self, stream: Callable[[], TextIO] = lambda: sys.stdin):
        self.stream = stream
        self.meanwhile = "the step waits"  # what becomes of the prompt while nobody can answer it
        self.prompt = ""  # the prompt waiting for its answer ('': none), asked again after `fg`
        self.heard: Callable[[bool], object] = _nobody_listens
        self._lock = threading.Lock()
        self._read: concurrent.futures.Future[str] | None = None
        self._loop: asyncio.AbstractEventLoop | None = None  # the latest prompt's: it says what the read meets

    def next_line(self, loop: asyncio.AbstractEventLoop) -> concurrent.futures.Future[str]:
        """The read under way, or a new one, for a prompt on `loop` (which from here on says what a
        background job's read meets): its result the line, EOFError at the end of the input."""
        with self._lock:  # held until the new read is recorded: its end, which forgets it, waits for that
            self._loop = loop
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

        self.next_line(loop).add_done_callback(on_loop(loop, settle))
        return await answered

    def _readline(self) -> str:
        """One line (a closed terminal's error raised: the prompt fails with it), the read forgotten
        once it ended: the next prompt starts another."""
        try:
            text = terminal_line(self.stream(), self._waiting)
        finally:
            with self._lock:
                self._read = None
        if not text:
            raise EOFError("standard input is closed")
        return text

    def _waiting(self, waiting: bool) -> None:
        """On the reader's thread: `_background` handed to the latest prompt's loop."""
        with self._lock:
            loop = self._loop
        if loop is not None:
            on_loop(loop, self._background)(waiting)

    def _background(self, waiting: bool) -> None:
        """On the loop: the background words (`waiting`), or the prompt asked again after `fg`."""
        if waiting:  # on a line of its own: the prompt waits at the end of its line
            say_aside("\n" + background_words("calibrate", self.meanwhile))
        elif self.prompt:
            with contextlib.suppress(OSError):  # the read goes on: its answer may still come
                say(f"{self.prompt}: ", nl=False)
        self.heard(waiting)


def _nobody_listens(waiting: bool) -> None:
    """`StandardInput.heard` while no prompt with a limit waits."""


STDIN = StandardInput()


def answerable() -> bool:
    """Standard input is a terminal, the command not a background job of it: someone can answer
    (closed at the start: None, nobody)."""
    try:
        return sys.stdin is not None and sys.stdin.isatty() and not in_background(sys.stdin)
    except ValueError:  # closed meanwhile
        return False


async def confirmed(prompt: str, limit: float | None = None, meanwhile: str = "the step waits") -> None:
    """The operator's Enter at the terminal (STDIN); CalibrationFailed if standard input is closed.
    `limit` (wall s): Unanswered once nobody could answer it that long (`answered`). `meanwhile`:
    what becomes of the prompt while nobody can answer it (a background job)."""
    STDIN.meanwhile, STDIN.prompt = meanwhile, prompt
    say(f"{prompt}: ", nl=False)
    try:
        await answered(limit)
    except BaseException as err:  # a cancellation among them: what follows starts on a line of its own
        with contextlib.suppress(OSError):  # an OutputError among them: the step is ending anyway
            say()
        if isinstance(err, (EOFError, OSError)):
            raise CalibrationFailed(f"{err}: nobody can confirm at the terminal") from None
        raise
    finally:
        STDIN.prompt = ""


async def answered(limit: float | None) -> None:
    """STDIN's next line. With a `limit` (wall s), Unanswered once nobody could answer for that long,
    as an unattended sweep's wait (orbitrig.run.unanswered): counted from the prompt if nobody can
    answer then (standard input not a terminal, or the command a background job of it: `answerable`),
    else from its read's failure as a background job's; lifted once it is brought to the foreground
    (`fg`), as the sweep's wait (RunEngine.attended_again), until the read fails again."""
    if limit is None:
        await STDIN.line()
        return
    t0 = time.monotonic()
    wait, wake = UnansweredWait(), asyncio.Event()
    if not answerable():
        wait.set_limit(limit)

    def heard(waiting: bool) -> None:
        wait.set_limit(limit if waiting else None)
        wake.set()

    read = asyncio.ensure_future(STDIN.line())
    read.add_done_callback(lambda _: wake.set())
    STDIN.heard = heard
    try:
        while not read.done():
            wake.clear()
            if await wait.until_woken(wake, t0) and not read.done():
                raise Unanswered(f"nobody could answer for {limit:g} s")
        read.result()
    finally:
        STDIN.heard = _nobody_listens
        read.cancel()
