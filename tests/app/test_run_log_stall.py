"""A stalled run.log holds neither the event loop nor an abort: run.log lines and the commands'
journal lines are written by a thread of their own (orbitrig.store.run_log).

The stall is real: run.log is a named pipe that nobody reads, so every open for writing blocks,
as a write to a hung network disk does. The run measures on, the abort's emergency stop goes
out at once, and the run's end waits for the lines, which are all there once the pipe is read."""

import asyncio
import os
import threading
import time

import pytest

from support.loop_beats import LoopBeats
from support.sweep_helpers import first_stop, running, small_matrix, wait_for

pytestmark = pytest.mark.timeout(120)
CW_EMERGENCY = 0x047B  # the spec's control word, written out here on purpose


class _PipeReader(threading.Thread):
    """Reads the named pipe until told to stop (the read end stays open: no writer blocks)."""

    def __init__(self, path):
        super().__init__(daemon=True)
        self.fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
        self.data, self.done = bytearray(), threading.Event()

    def run(self) -> None:
        while True:
            finished = self.done.is_set()
            try:
                while chunk := os.read(self.fd, 65536):
                    self.data += chunk
            except BlockingIOError:
                pass
            if finished:
                os.close(self.fd)
                return
            time.sleep(0.01)


class _Disk:
    """The stalled disk: comes back (a reader opens the pipe) when `back` is called, or by itself
    after LONGEST s, so that a loop that waits for it fails the test instead of hanging it."""

    LONGEST = 20.0

    def __init__(self, path):
        self.path, self.reader = path, None
        self._lock = threading.Lock()
        self._valve = threading.Timer(self.LONGEST, self.back)
        self._valve.start()

    def back(self) -> None:
        with self._lock:
            if self.reader is None:
                self.reader = _PipeReader(self.path)
                self.reader.start()

    def text(self) -> str:
        self._valve.cancel()
        self.back()
        self.reader.done.set()
        self.reader.join(5)
        return self.reader.data.decode()


async def test_a_stalled_run_log_holds_neither_the_loop_nor_an_abort(tmp_path):
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    os.mkfifo(run_dir / "run.log")  # nobody reads it: every line's write blocks
    disk = _Disk(run_dir / "run.log")
    try:
        async with (
            LoopBeats() as beats,
            running(tmp_path, small_matrix(spin_rpm=[1000.0, 2000.0])) as (sim, eng, rec, run),
        ):
            try:
                await wait_for(lambda: rec.blocks_done() >= 2, 60, what="blocks measured while run.log is stalled")
                t = time.monotonic()
                assert eng.request_abort(by="test") is True
                await wait_for(lambda: first_stop(sim, t, (CW_EMERGENCY,)) is not None, 10, what="the emergency stop")
                assert first_stop(sim, t, (CW_EMERGENCY,)) < 0.5
                await wait_for(lambda: max(abs(s) for s in sim.speeds) < 1.0, 30, what="the drives at rest")
                await asyncio.sleep(0.5)
                assert not run.done()  # the run's end waits for its log lines: none is lost
                assert beats.longest_gap() < 2.0, beats.longest_gap()  # the loop never waited for the disk (20 s)
            finally:
                disk.back()  # the disk comes back
            outcome = await asyncio.wait_for(asyncio.shield(run), 60)
    finally:
        text = disk.text()
    assert outcome.status == "aborted", outcome.message
    lines = text.splitlines()
    assert "provenance:" in lines[0] and "start run" in lines[1] and "command start by" in lines[3], lines[:4]
    assert any("command abort by test" in ln for ln in lines)
    assert any(ln.split(" ", 1)[1].startswith(f"run {eng.run_id} ended: aborted") for ln in lines[-3:]), lines[-3:]
    assert lines[-1].split(" ", 1)[1].startswith(f"[idle] run {eng.run_id} aborted")
    stamps = [ln.split(" ", 1)[0] for ln in lines]
    assert stamps == sorted(stamps)  # stamped when said, written in the order said
