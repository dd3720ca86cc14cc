"""The streams a command prints on, which can go away while the command runs.

A reader gone away is no failure of the command: a closed pipe (``| head``: writes fail with
EPIPE) or a hung-up terminal (EIO) must not end a sweep, a calibration or a hold half-way nor
change its exit status. Any other failure to write (a full disk or quota behind ``> file``:
ENOSPC, EDQUOT) loses output the user asked for, so the command fails: :func:`say` and
:func:`printing` raise it as an :class:`OutputError` naming the stream, which each command
reports at its boundary (an ``error:`` line, a non-zero exit). :func:`reader_gone` is that
rule; either way the stream is pointed at /dev/null (:func:`stream_gone`), so that what waits
in its buffer (the interpreter's flush at exit among it) goes nowhere instead of failing again.

:class:`TerminalConsole`, the rich console of a run's progress bars and operator lines (on
standard error, from inside signal handlers and the bars' thread), is the exception: it goes
quiet on any failure to write; the run log keeps the record.

A reader that stops reading without going away (Ctrl-S at the terminal, a pipe nobody reads)
makes a write wait until it reads again. The run's console writes through
:class:`BackgroundStream`, whose own thread does the writing: the event loop that polls the
drives and takes the signals never waits for the terminal.
"""

from __future__ import annotations

import collections
import contextlib
import errno
import os
import sys
import threading
from collections.abc import Iterator
from typing import Any, TextIO

import typer
from rich.console import Console


class OutputError(OSError):
    """Standard output (or error) could not be written for another reason than its reader
    gone (a full disk, a quota): ``filename`` names the stream."""

    def __str__(self) -> str:
        return f"cannot write {self.filename}: {self.strerror}"


def reader_gone(err: OSError) -> bool:
    """Whether `err` only says the reader went away: a broken pipe (EPIPE) or a hung-up
    terminal (EIO)."""
    return isinstance(err, BrokenPipeError) or err.errno in (errno.EPIPE, errno.EIO)


def say(message: str = "", *, err: bool = False, nl: bool = True) -> None:
    """``typer.echo`` on standard output (`err`: error) that a reader gone away does not fail
    (the stream is silenced and the command goes on); any other failure raises OutputError."""
    with printing(err=err):
        typer.echo(message, err=err, nl=nl)


@contextlib.contextmanager
def printing(*, err: bool = False) -> Iterator[None]:
    """A block that prints on standard output (`err`: error), flushed at its end: a reader gone
    away ends the printing only, never the command nor its exit status; any other failure of
    the stream (ENOSPC...) silences it and is raised as an OutputError. An OSError naming a
    file (``filename``: not the stream's, an OutputError among them) is raised as it is."""
    stream = sys.stderr if err else sys.stdout
    try:
        yield
        stream.flush()
    except OSError as e:
        if e.filename is not None:
            raise
        stream_gone(err=err)
        if not reader_gone(e):
            raise OutputError(e.errno, e.strerror, "standard error" if err else "standard output") from e


def stream_gone(*, err: bool = False) -> None:
    """Point standard output (`err`: error) at /dev/null: what waits in its buffer and every
    later write, the interpreter's flush at exit among them, go nowhere."""
    stream = sys.stderr if err else sys.stdout
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
        the thread of a BackgroundStream): before the process ends without its exit's waits."""
        if isinstance(self.file, BackgroundStream):
            self.file.finish(timeout)

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
    the run log keeps the record). ``finish`` waits for what was handed over, also at the
    process's exit."""

    def __init__(self, stream: TextIO):
        self._stream = stream
        self._waiting: collections.deque[str] = collections.deque()
        self._size = 0  # characters waiting
        self._busy = False  # a write under way
        self._gone = False
        self.dropped = 0  # characters not written: more than WAITING_MAX were waiting
        self._changed = threading.Condition()
        threading.Thread(target=self._write_all, name="terminal-writer", daemon=True).start()
        import atexit

        atexit.register(self.finish)  # after the threads that are no daemons (a stop's outcome)

    def write(self, text: str) -> int:
        with self._changed:
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
        """Nothing to wait for: the thread flushes what it writes."""

    def finish(self, timeout: float | None = None) -> bool:
        """Wait (at most ``timeout`` s) until what was handed over is written or the reader is gone."""
        with self._changed:
            return self._changed.wait_for(lambda: self._gone or not (self._waiting or self._busy), timeout)

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
                self._changed.wait_for(lambda: bool(self._waiting))
                text, self._busy = "".join(self._waiting), True
                self._waiting.clear()
                self._size = 0
            gone = False
            try:
                self._stream.write(text)
                self._stream.flush()
            except (OSError, ValueError):  # the reader gone, or the stream closed: quiet from here on
                gone = True
            with self._changed:
                self._busy, self._gone = False, self._gone or gone
                self._changed.notify_all()
