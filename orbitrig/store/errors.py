"""The store's errors: every failure to write or read a run directory is a StorageError;
a directory that is not a readable run (missing or damaged files, an unknown format) is a
RunDirError.

    OrbitrigError
    +-- StorageError(path, reason)              the run directory cannot be written or read
    |   +-- StorageFullError(path, problem, advice, needed, free)
    |   |                                       no space left (ENOSPC, EDQUOT) or too little free
    |   +-- UnusableRunDir(path, reason)        not usable as asked: holds a run already, no run
    |                                           to resume, a header that is not a run's
    +-- RunDirError(file, reason)               not a readable orbitrig run directory

No storage function lets an OSError or an HDF5 library error escape: `storage_error`
turns one into the matching StorageError, naming the file.
"""

from __future__ import annotations

import errno
import functools
import os
from typing import Any

from orbitrig.errors import OrbitrigError

#: what a new run is told of a run directory that holds a run already
RUN_EXISTS = "already exists: use --resume to continue that run, or another --out"

_FULL = {errno.ENOSPC, errno.EDQUOT}
#: errno values only a write gives (a full disk, a file too large, a read-only file system)
WRITE_ERRORS = frozenset(_FULL | {errno.EFBIG, errno.EROFS})
#: what a full disk advises unless told otherwise (a sweep's run directory)
FULL_ADVICE = "free space, then resume the run"
#: what a full disk advises before the run exists (its run.json not written)
FULL_AT_CREATE_ADVICE = "free space, then start the run again"


class StorageError(OrbitrigError):
    """The run directory cannot be created, resumed, written or read; ``path`` names the file."""

    def __init__(self, path: str | os.PathLike[str], reason: str):
        self.path, self.reason = str(path), reason
        super().__init__(f"{self.path}: {reason}")

    def __reduce__(
        self,
    ) -> tuple[Any, tuple[Any, ...]]:  # rebuilt from its fields where it crosses processes (report's workers)
        return type(self), (self.path, self.reason)


class StorageFullError(StorageError):
    """The file system of the run directory is full (or has less free space than a write needs):
    ``problem`` says what failed ('cannot write: No space left on device (the disk is full)',
    'needs 5.0 MB free, 1.0 MB left'), ``advice`` what to do; the reason is 'PROBLEM: ADVICE'."""

    def __init__(
        self,
        path: str | os.PathLike[str],
        problem: str,
        *,
        advice: str = FULL_ADVICE,
        needed: int | None = None,
        free: int | None = None,
    ):
        self.problem, self.advice = problem, advice
        self.needed, self.free = needed, free
        super().__init__(path, f"{problem}: {advice}")

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        rebuild = functools.partial(type(self), advice=self.advice, needed=self.needed, free=self.free)
        return rebuild, (self.path, self.problem)

    @classmethod
    def short_of(cls, path: str | os.PathLike[str], needed: int, free: int) -> StorageFullError:
        """Fewer than `needed` bytes free (`free`) for the run directory `path`: resume once there is room."""
        advice = "free space on this disk (or choose another --out), then resume the run"
        return cls(
            path, f"needs {_mb(needed)} free, {_mb(free)} left", advice=advice, needed=int(needed), free=int(free)
        )

    def advising(self, advice: str) -> StorageFullError:
        """The same error advising `advice` instead (an export: export again)."""
        return StorageFullError(self.path, self.problem, advice=advice, needed=self.needed, free=self.free)


class UnusableRunDir(StorageError):
    """The directory cannot be used as asked: it holds a run already (a new run), holds no run
    to resume, or its run.json is not a run's header. The caller's mistake, not a failure to
    write or read (`orbitrig sweep` exits 2 on it, 1 on any other StorageError)."""


class RunDirError(OrbitrigError):
    """DIR is not a readable orbitrig run directory; ``file`` names the culprit."""

    def __init__(self, file: str | os.PathLike[str], reason: str):
        self.file = str(file)
        self.reason = reason
        super().__init__(f"{self.file}: {reason}")

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        return type(self), (self.file, self.reason)


def storage_error(path: str | os.PathLike[str], doing: str, err: BaseException) -> StorageError:
    """The StorageError for `err` raised while `doing` (e.g. 'write', 'rename') on `path`."""
    if isinstance(err, StorageError):
        return err
    code = err.errno if isinstance(err, OSError) else None
    text = os.strerror(code) if isinstance(code, int) else str(err)
    if code in _FULL:
        return StorageFullError(path, f"cannot {doing}: {text} (the disk is full)")
    if code == errno.EIO and _read_only(path):
        text += " (the file system went read-only)"
    return StorageError(path, f"cannot {doing}: {type(err).__name__}: {text}")


def _read_only(path: str | os.PathLike[str]) -> bool:
    """Whether the file system holding `path` (or its nearest existing folder) now refuses writes
    as read-only: what the kernel makes of one on an I/O error (ext4 errors=remount-ro), whose
    writes in flight get EIO. Asked by creating an unnamed file there (O_TMPFILE, gone at its
    close): ext4's read-only state after an error shows in neither statvfs nor access()."""
    where = os.path.abspath(path)
    while not os.path.isdir(where) and os.path.dirname(where) != where:
        where = os.path.dirname(where)
    try:
        os.close(os.open(where, os.O_TMPFILE | os.O_WRONLY, 0o600))
    except OSError as err:
        return err.errno == errno.EROFS
    return False


def _mb(n: int) -> str:
    return f"{n / 1e6:.3g} MB" if n >= 1e5 else f"{n} bytes"
