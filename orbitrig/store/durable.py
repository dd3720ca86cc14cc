"""Durable writes: a file is either absent or whole (git's temp-fsync-rename discipline).

`write_atomic` writes the bytes to ``NAME.tmp``, flushes and fsyncs them, renames the
file into place and fsyncs the directory, so a kill or a power cut at any instant
leaves the old state or the new one, never a mixture. ``NAME.tmp`` is created new
(``O_CREAT | O_EXCL | O_NOFOLLOW``): a leftover (a file, or a symbolic link planted
there) is removed first, never followed, so no write lands outside the directory entry. `append_line` adds one line to
an append-only log and fsyncs it; `read_lines` returns the lines whose newline made
it to disk and counts a torn tail (or any line that does not parse) instead of failing.
`remove` takes a file away (one that is not there is no failure).

HDF5 never writes to the disk itself: `h5_image` builds a small file in memory (the
core driver without a backing store) and returns its bytes; `StreamedH5` builds a large
one (run.h5) through a Python file object on ``NAME.tmp``, so memory stays bounded
while it grows and a full disk is an ordinary OSError of Python's write. Either way
the HDF5 library is never left in a broken state.
Every OSError becomes a StorageError naming the file (orbitrig.store.errors).
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import itertools
import json
import os
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any, BinaryIO

from orbitrig.store.errors import StorageError, storage_error

if TYPE_CHECKING:
    import h5py

TMP_SUFFIX = ".tmp"
#: an append-only log: created when missing, a symbolic link at its name refused (never followed)
APPEND_FLAGS = os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC
_names = itertools.count()
_name_lock = threading.Lock()


def fsync_dir(directory: Path) -> None:
    """Make the directory entries (a rename, a new file) durable."""
    try:
        fd = os.open(directory, os.O_RDONLY | os.O_DIRECTORY)
    except OSError as err:
        raise storage_error(directory, "open the directory", err) from err
    try:
        os.fsync(fd)
    except OSError as err:
        raise storage_error(directory, "fsync the directory", err) from err
    finally:
        os.close(fd)


def _write_all(fd: int, data: bytes | memoryview) -> None:
    view = memoryview(data)
    while view:
        n = os.write(fd, view)
        view = view[n:]


def write_atomic(path: Path, data: bytes | memoryview) -> dict[str, int | str]:
    """Write `data` to `path` as one durable step (temp name, fsync, rename, fsync dir);
    return {"size": bytes, "sha256": hex digest} of what was written.

    On any failure the temporary file is removed and a StorageError is raised; the
    previous content of `path` (if any) is untouched."""
    with atomic_file(path) as f:
        f.write(data)
    return {"size": len(data), "sha256": hashlib.sha256(data).hexdigest()}


@contextlib.contextmanager
def atomic_file(path: Path) -> Iterator[BinaryIO]:
    """A binary file on ``NAME.tmp`` that becomes `path` as one durable step when the block
    ends (flush, fsync, rename, fsync dir), for content written piece by piece. On an
    OSError the temporary file is removed and a StorageError naming `path` is raised; the
    previous content of `path` (if any) is untouched."""
    path = Path(path)
    tmp = path.with_name(path.name + TMP_SUFFIX)
    fd = create_new(tmp)
    try:
        with os.fdopen(fd, "wb") as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except OSError as err:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise storage_error(path, "write", err) from err
    fsync_dir(path.parent)


def remove(path: Path) -> None:
    """Remove the file `path` if it is there; an OSError is the StorageError naming it."""
    try:
        path.unlink(missing_ok=True)
    except OSError as err:
        raise storage_error(path, "remove", err) from err


def create_new(tmp: Path, readable: bool = False) -> int:
    """Open a fresh temporary file for writing (0o644; also for reading when ``readable``, as
    HDF5 needs): a leftover at `tmp` (file or symbolic link) is unlinked, never followed; the
    open itself refuses anything there (``O_EXCL | O_NOFOLLOW``), so a link planted in between
    makes a StorageError, not a write."""
    try:
        os.unlink(tmp)
    except (FileNotFoundError, NotADirectoryError):
        pass  # no leftover (nor a folder for one): the open below names what is missing
    except OSError as err:
        if err.errno in (errno.EROFS, errno.EACCES, errno.EPERM) and not os.path.lexists(tmp):
            raise storage_error(tmp, "create", err) from err  # no leftover: the folder takes no new file
        raise storage_error(tmp, "remove the leftover temporary file", err) from err
    try:
        access = os.O_RDWR if readable else os.O_WRONLY
        return os.open(tmp, access | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
    except OSError as err:
        raise storage_error(tmp, "create", err) from err


def append_lines(path: Path, lines: list[str]) -> None:
    """Append `lines` (no newline inside any) in one write and fsync. A torn write leaves
    a partial last line that `read_lines` ignores; the next append starts on a fresh line."""
    if not lines:
        return
    data = "".join(line + "\n" for line in lines).encode("utf-8")
    try:
        fd = os.open(path, APPEND_FLAGS, 0o644)
    except OSError as err:
        raise storage_error(path, "open for appending", err) from err
    try:
        if os.fstat(fd).st_size and not _ends_with_newline(path):
            data = b"\n" + data  # a torn tail from a kill: it stays a line of its own
        _write_all(fd, data)
        os.fsync(fd)
    except OSError as err:
        raise storage_error(path, "append", err) from err
    finally:
        os.close(fd)


def _ends_with_newline(path: Path) -> bool:
    with open(path, "rb") as fh:
        fh.seek(-1, os.SEEK_END)
        return fh.read(1) == b"\n"


def read_lines(path: Path) -> tuple[list[tuple[int, dict[str, Any]]], int]:
    """The JSON objects of an append-only log, each with its line number (from 1), and how many
    lines were torn or unreadable."""
    try:
        data = Path(path).read_bytes()
    except FileNotFoundError:
        return [], 0
    except OSError as err:
        raise storage_error(path, "read", err) from err
    records, bad = [], 0
    lines = data.split(b"\n")
    if lines and lines[-1] == b"":
        lines.pop()
    elif lines:
        lines.pop()  # no newline: the tail of a write cut short
        bad += 1
    for number, raw in enumerate(lines, 1):
        try:
            rec = json.loads(raw)
        except (ValueError, RecursionError):
            rec = None
        if isinstance(rec, dict):
            records.append((number, rec))
        elif raw.strip():
            bad += 1
    return records, bad


def digest(path: Path) -> tuple[int, str]:
    """(size in bytes, SHA-256 hex) of a file."""
    h = hashlib.sha256()
    try:
        with open(path, "rb") as fh:
            for chunk in iter(lambda: fh.read(1 << 20), b""):
                h.update(chunk)
            size = fh.tell()
    except OSError as err:
        raise storage_error(path, "read", err) from err
    return size, h.hexdigest()


def memory_h5() -> h5py.File:
    """A new HDF5 file that lives in memory only (the core driver without a backing store)."""
    import h5py

    with _name_lock:
        name = f"orbitrig-mem-{os.getpid()}-{next(_names)}.h5"
    try:
        return h5py.File(name, "w", driver="core", backing_store=False)
    except (OSError, ValueError) as err:
        raise StorageError(name, f"cannot build an HDF5 file in memory: {err}") from err


def h5_image(build: Callable[[h5py.File], object]) -> bytes:
    """The bytes of an HDF5 file built in memory by ``build(h5py.File)``."""
    f = memory_h5()
    try:
        build(f)
        f.flush()
        image: bytes = f.id.get_file_image()
        return image
    finally:
        f.close()


class StreamedH5:
    """An HDF5 file written through Python's file I/O to ``PATH.tmp``; `commit` flushes,
    fsyncs and renames it to PATH (then fsyncs the directory), `discard` removes it. The
    file grows on disk as groups are added, so its size never sits in memory."""

    def __init__(self, path: Path):
        import h5py

        self.path = Path(path)
        self.tmp = self.path.with_name(self.path.name + TMP_SUFFIX)
        self._fh = os.fdopen(create_new(self.tmp, readable=True), "w+b")  # never follows a planted link
        try:
            self.file = h5py.File(self._fh, "w")
        except Exception as err:  # h5py reports a failed write in several types
            self.discard()
            raise storage_error(self.tmp, "start an HDF5 file in", err) from err

    def commit(self) -> Path:
        try:
            self.file.close()
            self._fh.flush()
            os.fsync(self._fh.fileno())
            self._fh.close()
            os.replace(self.tmp, self.path)
        except Exception as err:
            raise self.failed(err) from err
        fsync_dir(self.path.parent)
        return self.path

    def failed(self, err: Exception) -> StorageError:
        """What to raise for `err`, raised while this file was written: the temporary file is
        discarded first; a StorageError comes back as it is, anything else (h5py reports a failed
        write in several types) as the StorageError of writing PATH (a full disk: StorageFullError)."""
        self.discard()
        return storage_error(self.path, "write", err)

    def discard(self) -> None:
        """Close and remove the temporary file (best effort)."""
        for close in (getattr(self, "file", None), self._fh):
            with contextlib.suppress(Exception):
                if close is not None:
                    close.close()
        with contextlib.suppress(OSError):
            os.unlink(self.tmp)
