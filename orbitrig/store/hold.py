"""One process at a time writes a run: an exclusive advisory lock (flock) on its directory,
taken before a run or a resume moves or writes anything and gone with the process (a killed
one too: no stale lock to clear by hand). A second `sweep --resume` of a run still under way
(or still consolidating its run.h5) is refused instead of setting aside the point being
measured and removing the run.h5.tmp being written. A file system without locks (ENOLCK) is
logged and not refused."""

from __future__ import annotations

import errno
import fcntl
import logging
import os
from pathlib import Path

from orbitrig.store.errors import UnusableRunDir, storage_error

log = logging.getLogger(__name__)


class RunHold:
    """The lock on the run directory ``path``: `take` (UnusableRunDir when another process holds
    it), `release` (also when the hold is dropped)."""

    def __init__(self, path: Path):
        self.path = path
        self._fd: int | None = None

    def take(self) -> None:
        if self._fd is not None:
            return
        try:
            fd = os.open(self.path, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
        except OSError as err:
            raise storage_error(self.path, "open", err) from err
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as err:
            os.close(fd)
            if err.errno not in (errno.EWOULDBLOCK, errno.EAGAIN):
                log.warning("%s: cannot lock the run (%s): a second resume of it is not refused", self.path, err)
                return
            raise UnusableRunDir(
                self.path, "in use by another orbitrig process (the run or a resume of it): wait until it ends"
            ) from None
        self._fd = fd

    def __del__(self) -> None:  # a store dropped on a failure before its run's end lets go too
        self.release()

    def release(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
