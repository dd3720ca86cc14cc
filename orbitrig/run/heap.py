"""The process's C heap (glibc malloc) in a sweep or service that runs for months.

What grows over a long run is not what Python keeps (a finished point leaves only
its summary) but what the C allocator keeps after Python and numpy have freed it:
glibc gives each thread that allocates its own arena (up to 8 per core), raises its
mmap threshold every time a large block is freed (so the next blocks of raw counts,
means and identification temporaries, 0.1 to a few MB each, are carved out of those
arenas instead of being mapped and unmapped), and returns an arena's free memory to
the system only from its top. A point's blocks freed in the middle of an arena stay
resident: tens of MB per hundred points.

`tune_heap` (once, at the start of `sweep` and `serve`) caps the arenas at
HEAP_ARENAS and fixes the mmap threshold at MMAP_THRESHOLD (fixing it ends glibc's
raising of it), so large blocks are unmapped when freed; `trim_heap` (after every
completed point and every run) hands back what is still free inside the arenas
(malloc_trim). Variables the user set (MALLOC_ARENA_MAX, MALLOC_MMAP_THRESHOLD_)
win. Elsewhere than glibc both do nothing.
"""

from __future__ import annotations

import ctypes
import logging
import os
import sys

log = logging.getLogger(__name__)
HEAP_ARENAS = 2  # malloc arenas shared by all threads
MMAP_THRESHOLD = 256 * 1024  # bytes: larger blocks are mapped, and unmapped when freed
_M_MMAP_THRESHOLD, _M_ARENA_MAX = -3, -8  # mallopt parameters (malloc.h)


def _glibc() -> ctypes.CDLL | None:
    """The C library when it is glibc with mallopt and malloc_trim, else None."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        libc = ctypes.CDLL(None)
        for name in ("mallopt", "malloc_trim", "gnu_get_libc_version"):
            libc[name]  # AttributeError where the C library lacks it (musl, another libc)
    except (OSError, AttributeError):
        return None
    return libc


def tune_heap() -> None:
    """Cap the malloc arenas and fix the mmap threshold (unless set by the environment)."""
    libc = _glibc()
    if libc is None:
        return
    if "MALLOC_ARENA_MAX" not in os.environ and not libc.mallopt(_M_ARENA_MAX, HEAP_ARENAS):
        log.debug("mallopt(M_ARENA_MAX) refused")
    if "MALLOC_MMAP_THRESHOLD_" not in os.environ and not libc.mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD):
        log.debug("mallopt(M_MMAP_THRESHOLD) refused")


def trim_heap() -> None:
    """Return the free memory inside the malloc arenas to the system."""
    libc = _glibc()
    if libc is not None:
        libc.malloc_trim(0)
