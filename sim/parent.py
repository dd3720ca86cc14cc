"""The simulator as a child process: it ends when the process that started it ends.

Two independent ways, so that no orphaned simulator keeps its ports:

- Linux's parent-death signal (prctl PR_SET_PDEATHSIG): the kernel sends SIGTERM
  the moment the parent dies, SIGKILL included;
- the end of standard input: the parent holds the write end of a pipe and never
  writes; when it closes it (a clean stop) or dies, the simulator reads EOF.

The parent's death sends SIGTERM, which `serve_until_signalled` turns into a
clean stop (servers closed, CAN node off). The end of standard input is the
application's normal stop, and it waits for it: the simulator ends at once
(the kernel closes its sockets; its drives were stopped over Modbus before).
"""

from __future__ import annotations

import ctypes
import os
import signal
import threading

PR_SET_PDEATHSIG = 1


def end_with_parent(parent_pid: int) -> None:
    """SIGTERM to this process when `parent_pid` ends (or has already ended)."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)
    except (OSError, AttributeError):  # not Linux: the stdin watch alone
        pass
    if os.getppid() != parent_pid:  # the parent died before the signal was armed
        os.kill(os.getpid(), signal.SIGTERM)
    threading.Thread(target=_terminate_at_eof, name="parent-watch", daemon=True).start()


def _terminate_at_eof() -> None:
    try:
        while os.read(0, 4096):  # unbuffered: no lock that interpreter shutdown could find held
            pass
    except OSError:
        pass
    os._exit(0)
