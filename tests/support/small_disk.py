"""A small file system of the test's own, for the tests of a full or failing disk: a tmpfs, or
an ext4 image on a loop device that the kernel turns read-only as it does on an I/O error,
mounted (and lazily unmounted afterwards) with mount(8), which needs root."""

from __future__ import annotations

import contextlib
import os
import subprocess
from collections.abc import Iterator
from pathlib import Path


@contextlib.contextmanager
def mounted_tmpfs(folder: Path, size: str) -> Iterator[Path]:
    """``folder`` (made here) holding a tmpfs of ``size`` (mount's size=, e.g. "4m") until the end."""
    folder.mkdir()
    subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(folder)], check=True)
    try:
        yield folder
    finally:
        subprocess.run(["umount", "-l", str(folder)], check=False)


@contextlib.contextmanager
def mounted_ext4(folder: Path, size: str) -> Iterator[Path]:
    """``folder`` (made here) holding a fresh ext4 of ``size`` (truncate's size, e.g. "64M") on a
    loop device, mounted errors=remount-ro: `go_read_only` turns it read-only under the writers."""
    image = folder.with_name(folder.name + ".img")
    subprocess.run(["truncate", "-s", size, str(image)], check=True)
    subprocess.run(["mkfs.ext4", "-q", "-F", str(image)], check=True)
    folder.mkdir()
    subprocess.run(["mount", "-o", "loop,errors=remount-ro", str(image), str(folder)], check=True)
    try:
        yield folder
    finally:
        subprocess.run(["umount", "-l", str(folder)], check=False)
        image.unlink()


def go_read_only(folder: Path) -> None:
    """The ext4 mounted at ``folder`` read-only at once, open files and all, as the kernel does
    on an I/O error (errors=remount-ro): its sysfs trigger_fs_error; remount,ro refuses a busy one."""
    source = subprocess.run(["findmnt", "-no", "SOURCE", str(folder)], capture_output=True, text=True, check=True)
    device = os.path.basename(source.stdout.strip())
    Path(f"/sys/fs/ext4/{device}/trigger_fs_error").write_text("test: the disk went read-only\n")
