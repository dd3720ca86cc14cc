"""A run whose file system goes read-only under it (the kernel's remount-ro on an I/O error, on
a real ext4 image): both drives get their stop word before the storage failure is reported,
the run fails naming the directory, the points completed before stay readable and resume."""

from __future__ import annotations

import asyncio
import threading
import time

import pytest

from orbitrig.run.engine import StatusEvent
from orbitrig.store.durable import append_lines
from orbitrig.store.errors import StorageError
from orbitrig.store.reader import read_run
from support.small_disk import go_read_only, mounted_ext4
from support.sweep_helpers import first_stop, running, small_matrix, wait_for

pytestmark = pytest.mark.timeout(120)

# Spec control words, written out here (not imported from drives/) on purpose.
STOP_WORDS = (0x047E, 0x047B)


@pytest.fixture
def ext4_disk(tmp_path):
    with mounted_ext4(tmp_path / "disk", "64M") as mnt:
        yield mnt


async def test_a_disk_gone_read_only_stops_the_drives_first_and_keeps_the_points(ext4_disk):
    matrix = small_matrix(spin_rpm=[1000.0 + 100.0 * i for i in range(8)])  # the run lasts past the trigger
    async with running(ext4_disk, matrix) as (sim, eng, rec, run):
        out = ext4_disk / "run"
        await wait_for(lambda: (out / "points" / "0000" / "complete.json").exists(), 60, what="point 0000")
        t = time.monotonic()
        await asyncio.to_thread(go_read_only, ext4_disk)
        outcome = await asyncio.wait_for(asyncio.shield(run), 60)
        reported = [e for e in rec.events if isinstance(e, StatusEvent) and e.state == "faulted"]
        stop_after = first_stop(sim, t, STOP_WORDS)
    assert outcome.status == "failed", outcome.message
    assert str(out) in outcome.message and "read-only" in outcome.message.lower(), outcome.message
    assert reported, "the storage failure was never reported"
    assert stop_after is not None and stop_after < 2.0, stop_after
    assert read_run(out).points[0].complete


def test_a_write_in_flight_as_the_disk_goes_read_only_says_so(ext4_disk):
    """The kernel answers the writes in flight as it turns the disk read-only with EIO, which
    alone reads as a broken disk: the error names the file and says the file system went
    read-only (free space would not help; remount or check the disk)."""
    journal = ext4_disk / "journal.jsonl"
    failed: list[StorageError] = []

    def writer() -> None:
        while not failed:
            try:
                append_lines(journal, ['{"kind": "row"}'])
            except StorageError as err:
                failed.append(err)

    thread = threading.Thread(target=writer)
    thread.start()
    try:
        time.sleep(0.2)
        go_read_only(ext4_disk)
    finally:
        thread.join(10)
    assert failed and failed[0].path == str(journal)
    assert failed[0].reason in (  # EIO in flight, said; or EROFS, as the write that came after meets it
        "cannot append: OSError: Input/output error (the file system went read-only)",
        "cannot append: OSError: Read-only file system",
        "cannot open for appending: OSError: Read-only file system",
    ), failed[0].reason
