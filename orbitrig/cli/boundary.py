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

Which stream failed is asked of the stream, not read from the error alone (a file or a socket of
the command fails with the same errno): its reader is gone (poll: POLLERR, POLLHUP), it is a
regular file on a file system with no space left, at the file size limit (EFBIG) or whose
unwritten output the quota refuses again (EDQUOT), or a device that refuses even an empty write
(/dev/full). An error of neither stream is raised on as it was.

Nothing beyond the standard library is imported unless a stream failed (start-up:
bench/bench_startup.py).
"""

from __future__ import annotations

import errno
import os
import select
import stat
import sys
from collections.abc import Callable
from typing import NoReturn, TextIO


def run(command: Callable[[], object]) -> NoReturn:
    """Run `command` (click's standalone main: it ends in SystemExit), then exit as above."""
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
    names it; another error without a file name is the stream's that fails so now."""
    from orbitrig.cli.terminal import OutputError

    if isinstance(err, OutputError):
        return str(err.filename)
    if err.filename is not None:
        return None
    for name, stream in ((STDOUT, sys.stdout), (STDERR, sys.stderr)):
        try:
            fd = stream.fileno() if stream is not None else -1
        except (OSError, ValueError):
            continue
        if fd >= 0 and _fails(stream, fd, err):
            return name
    return None


def _fails(stream: TextIO, fd: int, err: OSError) -> bool:
    """Whether `stream` (descriptor `fd`) fails now as `err` says: its reader gone (EPIPE, EIO), or
    it cannot take more (ENOSPC and the like)."""
    from orbitrig.cli.terminal import reader_gone

    if reader_gone(err):
        poll = select.poll()
        poll.register(fd, select.POLLOUT)
        return any(events & (select.POLLERR | select.POLLHUP) for _, events in poll.poll(0))
    mode = os.fstat(fd).st_mode
    if stat.S_ISREG(mode):
        return _file_fails(stream, fd, err)
    if not stat.S_ISCHR(mode) or os.isatty(fd):  # a terminal is never full (and a stopped job's write waits)
        return False
    try:
        os.write(fd, b"")  # a device that refuses every write (/dev/full) refuses an empty one
    except OSError as probe:
        return probe.errno == err.errno
    return False


def _file_fails(stream: TextIO, fd: int, err: OSError) -> bool:
    """Whether a regular file (`stream` on `fd`) cannot take more as `err` says, asked of the file,
    not of the error (a file the command writes fails alike): ENOSPC, its file system full; EFBIG,
    its size at the largest a file may have (this process's RLIMIT_FSIZE); EDQUOT (a quota is no
    file's to ask), what it holds unwritten refused again: one whose write failed unbuffered
    (PYTHONUNBUFFERED) holds nothing, and the error is raised on as it is."""
    if err.errno == errno.ENOSPC:
        return os.fstatvfs(fd).f_bavail == 0
    if err.errno == errno.EFBIG:
        import resource

        limit = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
        return limit != resource.RLIM_INFINITY and os.fstat(fd).st_size >= limit
    if err.errno != errno.EDQUOT:
        return False
    try:
        stream.flush()
    except OSError as again:
        return again.errno == err.errno
    return False
