"""The command line's one boundary for its standard streams (`orbitrig.cli.main`): a failure to
write them that no command handled ends the process here, the same for every command, `--help`
and `--version` among them, once the command has returned or raised.

- Standard output's reader gone away (``| head``: EPIPE; a hung-up terminal: EIO): the printing
  ends, nothing is said, exit 0 (click's own handling said nothing and exited 1). Found once the
  command has ended (what `print` left in the buffer), the command's exit status stays.
- Standard output that cannot be written for another reason (``> file`` on a full disk: ENOSPC,
  EDQUOT, EFBIG): ``orbitrig COMMAND: error: standard output: No space left on device``, exit 1
  (the one error form, orbitrig.cli.failure; before: a traceback).
- Standard error that cannot be written: it is silenced, exit 1 (nothing more can be said); a
  usage error whose message it could not take keeps its exit 2 (click's other errors their own).

A command that goes on after printing (notes after its table, an exit status for skipped points)
prints in `orbitrig.cli.terminal.printing`, which ends the printing only and raises any other
failure as an OutputError naming the stream, handled here. The commands that move the drives
handle their streams themselves (both drives stopped first); the boundary sees what is left.

Which stream failed is said by the write that raised, not by the error alone (a file or a socket
of the command fails with the same errno) nor by the stream's file system (a file of the run's on
the same full disk as ``> file``): `run` writes descriptors 1 and 2 through a file of their own
(`StandardFile`), which raises a failure of theirs as an OutputError naming the stream and writes
all it is given, a short write going on with the rest (the unbuffered stream of ``python -u``
dropped the rest, and ``--help`` under ``ulimit -f`` exited 0, cut short). A reader gone away is
asked of the stream (poll: POLLERR, POLLHUP); an error of neither stream is raised on as it was.

Nothing beyond the standard library is imported unless a stream failed (start-up:
bench/bench_startup.py).
"""

from __future__ import annotations

import errno
import io
import select
import sys
from collections.abc import Callable
from typing import TYPE_CHECKING, NoReturn

if TYPE_CHECKING:
    from _typeshed import ReadableBuffer


def run(command: Callable[[], object]) -> NoReturn:
    """Run `command` (click's standalone main: it ends in SystemExit), then exit as above."""
    standard_files()
    try:
        command()
        code: int = 0
    except SystemExit as end:
        cause = end.__context__
        if end.code == 1 and isinstance(cause, OSError) and cause.errno == errno.EPIPE:
            _cut_short(cause, end)  # click's own handling of a broken pipe: exit 1, nothing said
        code = _status(end.code)
    except OSError as err:
        _cut_short(err, err, _ending(err))
    _flushed(code)


def _ending(err: OSError) -> int:
    """The exit status of the end the command was saying when `err` stopped it, its message not
    written: click's usage error (2) or another of its errors, a command's `failure.fail`
    (its typer.Exit); 0 for none."""
    from typer import Exit, TyperException  # TyperException: click's errors (UsageError: 2)

    cause, seen = err.__context__, 0
    while cause is not None and seen < 8:  # the message's own failure may be wrapped (OutputError)
        if isinstance(cause, (TyperException, Exit)):
            return cause.exit_code
        cause, seen = cause.__context__, seen + 1
    return 0


def _status(code: object) -> int:
    """A SystemExit's code as an exit status (None: 0; a message: 1, as Python exits)."""
    return code if isinstance(code, int) else 0 if code is None else 1


def _cut_short(err: OSError, raised: BaseException, code: int = 0) -> NoReturn:
    """The command ended by `err`: exit as the stream it came from says (`code`: the status of
    the end it was saying, else the printing's); `raised` is raised on when it came from
    neither standard stream."""
    stream = failed_stream(err)
    if stream is None:
        raise raised
    _exit(stream, err, code)


def _flushed(code: int) -> NoReturn:
    """What waits in standard output's buffer written (a command's `print`), then exit `code`."""
    try:
        if sys.stdout is not None:
            sys.stdout.flush()
    except OSError as err:
        _exit(STDOUT, err, code)
    raise SystemExit(code)


STDOUT, STDERR = "standard output", "standard error"


def _exit(stream: str, err: OSError, code: int) -> NoReturn:
    """`stream` failed with `err`: silence it; a reader gone keeps `code`, another failure of
    standard output is said in the one error form and exits 1 (`code` if it is a failure already);
    standard error: exit 1 (`code` if a failure)."""
    from orbitrig.cli.failure import EXIT_FAILED, say_error
    from orbitrig.cli.terminal import reader_gone, stream_gone

    stream_gone(err=stream == STDERR)
    if stream == STDOUT and reader_gone(err):
        raise SystemExit(code)
    if stream == STDOUT:
        try:
            say_error(f"{stream}: {err.strerror}")
        except OSError:  # standard error fails too: nothing can be said
            stream_gone(err=True)
    raise SystemExit(code or EXIT_FAILED)


def failed_stream(err: OSError) -> str | None:
    """The standard stream `err` came from (STDOUT, STDERR), None if neither: an OutputError
    names it (its write raised: `StandardFile`); a reader gone away without a file name is the
    stream's whose reader is gone now."""
    from orbitrig.cli.terminal import OutputError, reader_gone

    if isinstance(err, OutputError):
        return str(err.filename)
    if err.filename is not None or not reader_gone(err):
        return None
    for name, stream in ((STDOUT, sys.stdout), (STDERR, sys.stderr)):
        try:
            fd = stream.fileno() if stream is not None else -1
        except (OSError, ValueError):
            continue
        if fd >= 0 and _reader_gone_from(fd):
            return name
    return None


def _reader_gone_from(fd: int) -> bool:
    """Whether the reader of descriptor `fd` is gone (poll: POLLERR, POLLHUP)."""
    poll = select.poll()
    poll.register(fd, select.POLLOUT)
    return any(events & (select.POLLERR | select.POLLHUP) for _, events in poll.poll(0))


class StandardFile(io.FileIO):
    """Descriptor 1 or 2 as the file under standard output or error (``stream``: STDOUT, STDERR):
    a write writes all it is given, a short write (a disk filling, the file size limit) going on
    with the rest until it fails; a failure, its reader not gone, silences the stream (what waits
    in its buffer, the interpreter's flush at exit among it, goes nowhere: no write is made any
    more) and is raised as an OutputError naming it."""

    def __init__(self, fd: int, stream: str) -> None:
        super().__init__(fd, "wb", closefd=False)
        self.stream = stream
        self.failed = False

    def write(self, data: ReadableBuffer, /) -> int | None:  # type: ignore[override]
        view = memoryview(data).cast("B")
        if self.failed:
            return len(view)
        done = 0
        while done < len(view):
            try:
                written = super().write(view[done:])
            except OSError as err:
                failure = _stream_failure(self.stream, err)
                if failure is err:
                    raise
                self.failed = True
                raise failure from err
            if written is None:  # a non-blocking descriptor that takes nothing now (None: nothing at all)
                return done or None
            done += written
        return done


def _stream_failure(stream: str, err: OSError) -> OSError:
    """What a failed write of `stream` raises: `err` itself if its reader is gone (the printing
    ends, orbitrig.cli.terminal.printing), else the stream silenced and an OutputError naming it."""
    from orbitrig.cli.terminal import OutputError, reader_gone, stream_gone

    if reader_gone(err):
        return err
    stream_gone(err=stream == STDERR)
    return OutputError(err.errno, err.strerror, stream)


def standard_files() -> None:
    """Standard output and error written through a StandardFile each, buffered as they were
    (``python -u``: unbuffered); a stream that is no text file of descriptor 1 or 2 stays."""
    for fd, name in ((1, STDOUT), (2, STDERR)):
        stream = sys.stdout if fd == 1 else sys.stderr
        try:
            if not isinstance(stream, io.TextIOWrapper) or stream.fileno() != fd:
                continue
            stream.flush()
        except (OSError, ValueError):  # closed, or no descriptor
            continue
        raw = StandardFile(fd, name)
        binary = raw if isinstance(stream.buffer, io.RawIOBase) else io.BufferedWriter(raw)
        text = io.TextIOWrapper(
            binary,
            encoding=stream.encoding,
            errors=stream.errors,
            newline="\n",
            line_buffering=stream.line_buffering,
            write_through=stream.write_through,
        )
        if fd == 1:
            sys.stdout = text
        else:
            sys.stderr = text
