"""A raw pseudo-terminal for a simulated serial device.

    master, slave, path = open_raw_pty()   # the device works the master; clients open `path`

The slave end is set raw (no echo, no line editing, no output processing)
before any client opens it, and the caller keeps `slave` open for the pty's
life: clients may then open and close `path` repeatedly without the master
seeing a hang-up. The master is non-blocking, for `loop.add_reader`.
"""

from __future__ import annotations

import contextlib
import os
import tty

__all__ = ["close_fds", "open_raw_pty"]


def open_raw_pty() -> tuple[int, int, str]:
    """Open a pty: (master fd, non-blocking; slave fd, raw; slave path)."""
    master, slave = os.openpty()
    try:
        tty.setraw(slave)
        os.set_blocking(master, False)
        path = os.ttyname(slave)
    except BaseException:
        close_fds(master, slave)
        raise
    return master, slave, path


def close_fds(*fds: int | None) -> None:
    """Close the given descriptors, ignoring ones already closed (None skipped)."""
    for fd in fds:
        if fd is not None:
            with contextlib.suppress(OSError):
                os.close(fd)
