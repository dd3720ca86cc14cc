"""A serial cable for tests: a socat pty pair, one end a path for the drives' URL, the other an fd."""

from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path


@contextlib.contextmanager
def serial_cable(tmp_path: Path) -> Iterator[tuple[str, int]]:
    """A socat pty pair: (the drives' end, a path; the far end, an open fd)."""
    assert shutil.which("socat"), "socat is installed by tools/run-tests"
    near, far = tmp_path / "ttyDRIVES", tmp_path / "ttyFAR"
    proc = subprocess.Popen(
        ["socat", f"pty,raw,echo=0,link={near}", f"pty,raw,echo=0,link={far}"], stderr=subprocess.DEVNULL
    )
    try:
        deadline = time.monotonic() + 10
        while not (near.exists() and far.exists()):
            assert proc.poll() is None and time.monotonic() < deadline, "socat made no pty pair"
            time.sleep(0.02)
        fd = os.open(far, os.O_RDWR | os.O_NOCTTY)
        try:
            yield str(near), fd
        finally:
            os.close(fd)
    finally:
        proc.terminate()
        proc.wait(10)
