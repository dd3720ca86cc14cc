"""The drives stop first, on the real simulator: an operator stop does not wait for the storage
or identification in flight (the earlier points are still stored), and an abort or a stop at
once sends its stop words whatever the disk does (run.log, the command journal).

Slow storage cannot be produced by the real parts: an identification that hangs until released
and a run.log / journal write that takes a second are injected (tests/app/test_run_log_stall.py
stalls run.log for real)."""

import asyncio
import threading
import time

import pytest

import orbitrig.run.point_record as point_record
from orbitrig.run.engine import ProgressEvent
from orbitrig.store.run_log import RunLog
from orbitrig.store.writer import RunStore
from support.sweep_helpers import first_stop, running, small_matrix, wait_for

pytestmark = pytest.mark.timeout(90)

# Spec control words, written out here (not imported from drives/) on purpose.
CW_RAMP_STOP, CW_EMERGENCY = 0x047E, 0x047B


STOP_WORDS = (CW_RAMP_STOP, CW_EMERGENCY)


async def test_a_stop_does_not_wait_for_the_identification_in_flight(tmp_path, monkeypatch):
    release = threading.Event()
    real = point_record.identify_operating_point

    def hanging(*args, **kw):  # a loaded machine: point 1 is identified long after it was measured
        release.wait(30)
        return real(*args, **kw)

    monkeypatch.setattr(point_record, "identify_operating_point", hanging)
    async with running(tmp_path, small_matrix(spin_rpm=[1000.0, 2000.0])) as (sim, eng, rec, run):

        def at_point_2() -> bool:
            return any(isinstance(e, ProgressEvent) and e.point >= 2 and e.frequency >= 1 for e in rec.events)

        await wait_for(at_point_2, 60, what="point 2")
        t = time.monotonic()
        eng.request_stop(by="test")
        try:
            await wait_for(lambda: first_stop(sim, t, STOP_WORDS) is not None, 10, what="a stop word")
            assert first_stop(sim, t, STOP_WORDS) < 1.0
        finally:
            release.set()
        outcome = await asyncio.wait_for(asyncio.shield(run), 60)
        assert outcome.status == "stopped", outcome.message
        assert outcome.completed_points == [0]  # the point identified after the stop is stored complete


@pytest.mark.parametrize("request_kind", ["stop_now", "abort"])
async def test_the_stop_words_go_out_before_any_disk_write(tmp_path, monkeypatch, request_kind):
    armed, blocked = threading.Event(), []

    def slow(real):
        def write(self, *args):
            if armed.is_set():
                armed.clear()
                blocked.append(time.monotonic())
                time.sleep(1.0)  # a busy or network disk
            return real(self, *args)

        return write

    monkeypatch.setattr(RunStore, "_journal", slow(RunStore._journal))
    monkeypatch.setattr(RunLog, "_append", slow(RunLog._append))
    async with running(tmp_path, small_matrix(spin_rpm=[1000.0, 2000.0])) as (sim, eng, rec, run):
        await wait_for(lambda: rec.blocks_done() >= 2, 60, what="blocks")
        t = time.monotonic()
        armed.set()
        if request_kind == "abort":
            eng.request_abort(by="test")
        else:
            eng.request_stop_now("SIGTERM", by="test")
        outcome = await asyncio.wait_for(asyncio.shield(run), 60)
        word = CW_EMERGENCY if request_kind == "abort" else CW_RAMP_STOP
        first = first_stop(sim, t, (word,))
        assert blocked, "no disk write was slowed"
        assert first is not None and first < 0.5, first
        assert outcome.status == ("aborted" if request_kind == "abort" else "stopped"), outcome.message
    commands = [ln for ln in (tmp_path / "run" / "run.log").read_text().splitlines() if "command" in ln]
    assert any(("command abort" if request_kind == "abort" else "command stop") in ln for ln in commands)
