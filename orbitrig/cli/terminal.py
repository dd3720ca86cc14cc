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
"""

from __future__ import annotations

import contextlib
import errno
import os
import sys
from collections.abc import Iterator
from typing import Any

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

    def gone(self) -> None:
        """The terminal is gone: drop what waits to be written and write nothing more."""
        self.quiet = True
        del self._buffer[:]
