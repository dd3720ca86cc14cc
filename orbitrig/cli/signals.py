"""Signals that end a command which moves the drives: SIGINT (Ctrl-C), SIGTERM (a service
manager, a shutdown), SIGHUP (a closed terminal) and SIGQUIT (Ctrl-\\, handled as SIGTERM: no
core dump while the drives turn); and the output such a command writes, which a reader gone
away (a broken pipe: ``| head``; a hung-up terminal) must not end either.

:func:`run_until_signal` runs a coroutine whose way out stops both drives (an ``async with``
of the rig) and cancels it on the first of these signals, so the drives are stopped on each
of them as on Ctrl-C; the signal comes back as :class:`Interrupted`. Further signals during
that stop are only counted: the stop under way is not cut short.

:func:`say` and :func:`printing` write to standard output or error; when the stream fails its
file descriptor is pointed at /dev/null, so that the rest (the flush at exit among it) goes
nowhere instead of failing the command half-way or changing its exit status.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import os
import signal
import sys
from collections.abc import Awaitable, Callable, Iterator
from typing import TypeVar

import typer

T = TypeVar("T")

SIGNALS: tuple[signal.Signals, ...] = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT)
#: the signals in words, for help texts
SIGNAL_WORDS = "Ctrl-C, SIGTERM, SIGHUP or SIGQUIT"


class Interrupted(Exception):
    """The command was cancelled by `sig` (its drives were stopped on the way out)."""

    def __init__(self, sig: signal.Signals):
        super().__init__(signal_name(sig))
        self.sig = sig


def signal_name(sig: int) -> str:
    """'Ctrl-C' for SIGINT, else the signal's name ('SIGTERM')."""
    return "Ctrl-C" if sig == signal.SIGINT else signal.Signals(sig).name


def run_until_signal(make: Callable[[], Awaitable[T]]) -> T:
    """``asyncio.run(make())``, cancelled by the first of SIGNALS (raises Interrupted after the
    coroutine's own way out has run)."""

    async def main() -> T:
        task = asyncio.current_task()
        assert task is not None
        loop = asyncio.get_running_loop()
        received: list[signal.Signals] = []

        def on_signal(sig: signal.Signals) -> None:
            received.append(sig)
            if len(received) == 1:
                task.cancel()

        for sig in SIGNALS:
            loop.add_signal_handler(sig, on_signal, sig)
        try:
            return await make()
        except asyncio.CancelledError:
            if not received:
                raise
            task.uncancel()
            raise Interrupted(received[0]) from None
        finally:
            for sig in SIGNALS:
                loop.remove_signal_handler(sig)

    return asyncio.run(main())


def say(message: str = "", *, err: bool = False, nl: bool = True) -> None:
    """``typer.echo`` that cannot fail the command: a stream that fails (a broken pipe, a closed
    terminal) is silenced (`stream_gone`) and the command goes on."""
    try:
        typer.echo(message, err=err, nl=nl)
    except OSError:
        stream_gone(err=err)


@contextlib.contextmanager
def printing(*, err: bool = False) -> Iterator[None]:
    """A block that prints on standard output (`err`: error), flushed at its end: a reader gone
    away (EPIPE, EIO) ends the printing only, never the command nor its exit status."""
    stream = sys.stderr if err else sys.stdout
    try:
        yield
        stream.flush()
    except OSError as e:
        if not isinstance(e, BrokenPipeError) and e.errno != errno.EIO:
            raise
        stream_gone(err=err)


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
