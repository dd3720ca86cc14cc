"""The streams a command prints on, which can go away while the command runs.

A reader gone away is no failure of the command: a closed pipe (``| head``: writes fail with
EPIPE) or a hung-up terminal (EIO) must not end a sweep, a calibration or a hold half-way nor
change its exit status. Any other failure to write (a full disk or quota behind ``> file``:
ENOSPC, EDQUOT, EFBIG) loses output the user asked for, so the command fails: the stream's own
write raises it as an :class:`OutputError` naming the stream (orbitrig.cli.boundary.StandardFile),
which :func:`say` and :func:`printing` raise on and the command line's boundary reports unless the
command does (the ``error:`` line, exit 1; it also ends a plain ``typer.echo`` that failed,
`--help` among them). :func:`reader_gone` is that
rule; either way the stream is pointed at /dev/null (:func:`stream_gone`), so that what waits
in its buffer (the interpreter's flush at exit among it) goes nowhere instead of failing again.

:class:`TerminalConsole`, the rich console of a run's progress bars and operator lines (on
standard error, from inside signal handlers and the bars' thread), is the exception: it goes
quiet on any failure to write; the run log keeps the record.

A reader that stops reading without going away (Ctrl-S at the terminal, a pipe nobody reads)
makes a write wait until it reads again. While a command that moves the drives (a sweep, a
calibration, `drives run`) runs its event loop, standard output and error are each a
:class:`BackgroundStream`, whose own thread does the writing (:func:`off_the_loop`), the run's
console among what writes on them: the loop that polls the drives and takes the signals never
waits for the terminal. What such a command prints once its loop is done goes straight to the
stream again.

A command that commands the drives ignores SIGTTIN and SIGTTOU (orbitrig.cli.signals): as a
background job of its terminal (``orbitrig sweep ... &``, ``bg``) its writes go through and a read
of the terminal fails (EIO) instead of stopping the process. :func:`terminal_line`, the operator's
prompts' one read, takes such a failure for "nobody can answer here" until the job is brought to
the foreground (``fg``), then reads again.
"""

from __future__ import annotations

import atexit
import collections
import contextlib
import errno
import os
import sys
import threading
import time
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any, TextIO, TypeVarTuple, Unpack

import typer
from rich.console import Console

from orbitrig.cli.boundary import STDERR, STDOUT

if TYPE_CHECKING:  # asyncio not imported at `orbitrig --help`
    import asyncio


class OutputError(OSError):
    """Standard output (or error) could not be written for another reason than its reader
    gone (a full disk, a quota, the file size limit), raised by its own write: ``filename`` names
    the stream ('standard output: No space left on device', the one wording of
    orbitrig.cli.boundary)."""

    def __str__(self) -> str:
        return f"{self.filename}: {self.strerror}"  # as the command line's boundary says it


def reader_gone(err: OSError) -> bool:
    """Whether `err` only says the reader went away: a broken pipe (EPIPE) or a hung-up
    terminal (EIO)."""
    return isinstance(err, BrokenPipeError) or err.errno in (errno.EPIPE, errno.EIO)


#: wall s between two looks whether a background job has been brought to the foreground (`fg`)
FOREGROUND_POLL_S = 0.2


def in_background(stream: Any) -> bool:
    """Whether `stream` is this process's controlling terminal and another process group is in its
    foreground (a background job: its read fails with EIO while SIGTTIN is ignored)."""
    try:
        return os.tcgetpgrp(stream.fileno()) != os.getpgrp()
    except (OSError, ValueError):  # not a terminal, not ours, closed or hung up
        return False


def terminal_line(stream: Any, waiting: Callable[[bool], object]) -> str:
    """``stream.readline()`` ('' at the end of the input); a read that fails as a background job's
    does (EIO, `in_background`) calls ``waiting(True)``, waits until the process is in the
    terminal's foreground again (`fg`), calls ``waiting(False)`` and reads again. Any other failure
    (a hung-up terminal) is raised."""
    while True:
        try:
            return stream.readline()
        except OSError as err:
            if err.errno != errno.EIO or not in_background(stream):
                raise
        waiting(True)
        while in_background(stream):
            time.sleep(FOREGROUND_POLL_S)
        waiting(False)


#: the arguments of a call handed to an event loop (`on_loop`): checked as the call's own
_Args = TypeVarTuple("_Args")


def on_loop(
    loop: asyncio.AbstractEventLoop, call: Callable[[Unpack[_Args]], object]
) -> Callable[[Unpack[_Args]], None]:
    """``call`` for a terminal's reader thread (`terminal_line`'s `waiting`, the line it read): each
    call handed to `loop`'s thread, which owns what the prompt writes and waits on (its lines stay
    in order with the loop's own); none once the loop is closed (nobody waits for the prompt)."""

    def handed(*args: Unpack[_Args]) -> None:
        with contextlib.suppress(RuntimeError):  # the loop is closed
            loop.call_soon_threadsafe(call, *args)

    return handed


def background_words(command: str, meanwhile: str) -> str:
    """What `orbitrig <command>` says once its prompt's read failed as a background job's
    (`terminal_line`); `meanwhile`: what becomes of the prompt nobody can answer there."""
    return (
        f"prompt waiting: orbitrig {command} is a background job of its terminal and cannot read it; "
        f"bring it to the foreground (fg) to answer. Meanwhile {meanwhile}"
    )


def say(message: str = "", *, err: bool = False, nl: bool = True) -> None:
    """``typer.echo`` on standard output (`err`: error) that a reader gone away does not fail
    (the stream is silenced and the command goes on); any other failure raises OutputError."""
    with printing(err=err):
        typer.echo(message, err=err, nl=nl)


def say_aside(message: str) -> None:
    """`say` on standard error words the command's outcome does not rest on (how a way out left the
    drives, a warning around a stop): one that cannot be written (a full disk) is left unsaid, and
    the exit status still says what happened, not the failure of the output."""
    with contextlib.suppress(OutputError):
        say(message, err=True)


@contextlib.contextmanager
def printing(*, err: bool = False) -> Iterator[None]:
    """A block that prints on standard output (`err`: error), flushed at its end: a reader gone
    away ends the printing only, never the command nor its exit status; any other failure of
    the stream (ENOSPC...) silences it and is raised, the OutputError its write raised
    (orbitrig.cli.boundary.StandardFile). Another OSError (a file's, another stream's) is raised
    as it is."""
    stream = sys.stderr if err else sys.stdout
    try:
        yield
        stream.flush()
    except OSError as e:
        ours = isinstance(e, OutputError) and e.filename == (STDERR if err else STDOUT)
        if not ours and (e.filename is not None or not reader_gone(e)):
            raise
        stream_gone(err=err)
        if ours:
            raise


#: wall s a command waits for standard output to take what it printed before it acts on that
#: output's fate (`drives run` before it leaves the drives at the setpoint)
OUTPUT_WAIT_S = 2.0


async def output_taken(timeout: float = OUTPUT_WAIT_S) -> None:
    """Wait, off the loop, at most `timeout` wall s until what was printed on standard output has
    been written (its BackgroundStream's thread) or its reader is gone; a write that failed for
    another reason (ENOSPC) is raised here as an OutputError (as `printing` does), not once the
    command's loop is done."""
    import asyncio

    if isinstance(sys.stdout, BackgroundStream):
        await asyncio.to_thread(sys.stdout.finish, timeout)
    with printing():
        pass


def stream_gone(*, err: bool = False) -> None:
    """Point standard output (`err`: error) at /dev/null: what waits in its buffer and every
    later write, the interpreter's flush at exit among them, go nowhere."""
    _to_devnull(sys.stderr if err else sys.stdout)


def _to_devnull(stream: Any) -> None:
    with contextlib.suppress(OSError, ValueError):
        fd = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(fd, stream.fileno())
        finally:
            os.close(fd)


class TerminalConsole(Console):
    """rich Console that stops writing (``quiet``) when its file fails, instead of raising; its
    log lines carry the time but not the source file and line (an operator's terminal)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("log_path", False)
        super().__init__(*args, **kwargs)

    def _check_buffer(self) -> None:
        try:
            super()._check_buffer()
        except OSError:
            self.gone()

    def on_broken_pipe(self) -> None:
        self.gone()

    def written(self, timeout: float | None = None) -> None:
        """Wait (at most ``timeout`` s) until what was printed has reached the stream (written by
        the thread of a BackgroundStream): before the process ends without its exit's waits, or
        the stream is given back (`off_the_loop`). A failure to write it makes the console quiet
        here, as any other of its failures, instead of failing the command later."""
        if isinstance(self.file, BackgroundStream):
            self.file.finish(timeout)
            try:
                self.file.flush()  # raises what the thread met after the console's last flush
            except OSError:
                self.gone()

    def gone(self) -> None:
        """The terminal is gone: drop what waits to be written and write nothing more."""
        self.quiet = True
        del self._buffer[:]


#: characters a BackgroundStream keeps waiting for its reader; beyond, what is written is dropped
WAITING_MAX = 1_000_000


class BackgroundStream:
    """A text stream (``stream``: standard error) written by a thread of its own: ``write`` hands
    the text over and returns at once, so that a reader that stops reading (Ctrl-S, a pipe nobody
    reads) holds that thread only. Beyond WAITING_MAX characters waiting, the text is dropped
    (``dropped`` counts it); once a write fails, the stream writes nothing more (the reader is gone:
    the run log keeps the record; another failure, ENOSPC, is raised at the next ``flush``).
    ``finish`` waits for what was handed over, also at the process's exit; ``close`` ends the
    thread."""

    def __init__(self, stream: TextIO):
        self._stream = stream
        self._waiting: collections.deque[str] = collections.deque()
        self._size = 0  # characters waiting
        self._busy = False  # a write under way
        self._gone = False
        self.dropped = 0  # characters not written: more than WAITING_MAX were waiting
        self.unsaid: OSError | None = None  # a write that failed, its reader not gone; not raised yet
        self._changed = threading.Condition()
        self._closed = False  # `close`d: the thread ends, later writes go to the stream at once
        threading.Thread(target=self._write_all, name="terminal-writer", daemon=True).start()
        atexit.register(self.finish)  # after the threads that are no daemons (a stop's outcome)

    def write(self, text: str) -> int:
        if not isinstance(text, str):  # a text stream (click asks whether bytes are taken)
            raise TypeError(f"write() argument must be str, not {type(text).__name__}")
        with self._changed:
            if self._closed and not self._gone:
                return self._stream.write(text)
            if self._gone:
                return len(text)
            if self._size + len(text) > WAITING_MAX:
                self.dropped += len(text)
                return len(text)
            self._waiting.append(text)
            self._size += len(text)
            self._changed.notify_all()
        return len(text)

    def flush(self) -> None:
        """Nothing to wait for (the thread flushes what it writes); a write that failed for another
        reason than its reader gone (ENOSPC) and was not raised yet is raised here, once."""
        with self._changed:
            failure, self.unsaid = self.unsaid, None
            closed = self._closed and not self._gone
        if failure is not None:
            raise failure
        if closed:
            self._stream.flush()

    def finish(self, timeout: float | None = None) -> bool:
        """Wait (at most ``timeout`` s) until what was handed over is written or the reader is gone."""
        with self._changed:
            return self._changed.wait_for(lambda: self._gone or not (self._waiting or self._busy), timeout)

    def close(self) -> None:
        """What waits written (`finish`, the reader willing), then the thread ends; from here on a
        write goes to the stream at once (no event loop of a drive command waits on it any more)."""
        self.finish()
        with self._changed:
            self._closed = True
            self._changed.notify_all()
        atexit.unregister(self.finish)

    def isatty(self) -> bool:
        return self._stream.isatty()

    def fileno(self) -> int:
        return self._stream.fileno()

    @property
    def encoding(self) -> str:
        return self._stream.encoding or "utf-8"

    def _write_all(self) -> None:
        while True:
            with self._changed:
                self._changed.wait_for(lambda: bool(self._waiting) or self._closed)
                if not self._waiting:
                    return
                text, self._busy = "".join(self._waiting), True
                self._waiting.clear()
                self._size = 0
            failure: OSError | None = None
            gone = False
            try:
                self._stream.write(text)
                self._stream.flush()
            except OSError as err:  # quiet from here on; raised at the next flush unless the reader is gone
                gone, failure = True, None if reader_gone(err) else err
                _to_devnull(self._stream)  # what is left in its buffer goes nowhere (the exit's flush)
            except ValueError:  # the stream closed
                gone = True
            with self._changed:
                self._busy, self._gone = False, self._gone or gone
                self.unsaid = self.unsaid or failure
                self._changed.notify_all()


@contextlib.contextmanager
def off_the_loop() -> Iterator[None]:
    """Standard output and error written by threads of their own (BackgroundStream) for the block:
    a command that moves the drives runs its event loop in it. Then what waits is written (once the
    reader reads) and the streams are given back; a write that failed for another reason than its
    reader gone, not raised yet, is raised as an OutputError naming the stream (as `printing` does)."""
    streams = {STDOUT: sys.stdout, STDERR: sys.stderr}
    sys.stdout, sys.stderr = BackgroundStream(sys.stdout), BackgroundStream(sys.stderr)
    taken = {STDOUT: sys.stdout, STDERR: sys.stderr}
    try:
        yield
    finally:
        sys.stdout, sys.stderr = streams[STDOUT], streams[STDERR]
        for stream in taken.values():
            stream.close()
    for name, stream in taken.items():
        if stream.unsaid is not None:
            raise OutputError(stream.unsaid.errno, stream.unsaid.strerror, name)
