"""A run whose disk never returns, on the real simulator: the stop ends with both drives at
standstill, and the run, still stopping, says so and names what it waits for (its status, again
every STORAGE_NOTE_S while it waits); once the disk is back it ends stopped with every block kept.

A disk that never returns cannot be produced by the real parts: the block writes hang until the
test releases them (tests/app/test_run_log_stall.py stalls run.log for real)."""

import asyncio
import threading

import pytest

import orbitrig.run.background as background
import orbitrig.run.closing as closing
from orbitrig.run.engine import NoteEvent, NoteKind, StatusEvent
from orbitrig.run.states import STOPPING
from orbitrig.store.writer import RunStore
from support.rig_configs import patient_rig
from support.sweep_helpers import running, small_matrix, wait_for

pytestmark = pytest.mark.timeout(120)


def _waiting(rec) -> list[str]:
    return [e.message for e in rec.events if isinstance(e, StatusEvent) and "waiting for the storage" in e.message]


async def test_a_stopping_run_whose_disk_never_returns_says_its_drives_stopped_and_what_it_waits_for(
    tmp_path, monkeypatch
):
    stall, release = _stalled_blocks(monkeypatch)
    monkeypatch.setattr(closing, "STORAGE_NOTE_S", 1.0)
    monkeypatch.setattr(closing, "DISK_STALL_S", 1.0)
    async with running(tmp_path, small_matrix(spin_rpm=[1000.0, 2000.0])) as (sim, eng, rec, run):
        try:
            await wait_for(lambda: rec.blocks_done() >= 2, 60, what="two blocks")
            stall.set()
            await wait_for(lambda: rec.blocks_done() >= 3, 60, what="a block behind the stalled write")
            eng.request_stop_now("SIGTERM", by="test")
            await wait_for(lambda: _waiting(rec), 30, what="the stopping status naming the wait")
            first = _waiting(rec)[0]
            assert eng.state == STOPPING and not run.done()
            assert all(abs(w) < 1e-3 for w in sim.speeds), sim.speeds  # said once both are at standstill
            assert first.startswith("drives: ramp stop (OFF1); standstill after"), first
            assert "waiting for the storage in flight: store 0000/" in first, first
            await wait_for(lambda: any("(for 2 s)" in m for m in _waiting(rec)), 10, what="the wait's note")
            assert eng.state == STOPPING and not run.done() and eng.waiting_for_disk  # one write stalled 1 s+
        finally:
            release.set()
        outcome = await asyncio.wait_for(asyncio.shield(run), 60)
    assert outcome.status == "stopped", outcome.message
    assert not eng.waiting_for_disk and eng.unwritten() == []
    log = (tmp_path / "run" / "run.log").read_text()
    assert "waiting for the storage in flight: store 0000/" in log


# Spec control words, written out here (not imported from drives/) on purpose.
CW_RAMP_STOP = 0x047E


def _stalled_blocks(monkeypatch) -> tuple[threading.Event, threading.Event]:
    """(stall, release): once `stall` is set the run's block writes hang until `release` is set;
    the wait for the points before a point says so every 0.5 s (its NoteEvent STORAGE_WAIT)."""
    stall, release = threading.Event(), threading.Event()
    real = RunStore.write_block

    def hanging(self, point, rec):
        if stall.is_set():
            release.wait(90)  # the disk never returns, until the test lets it
        return real(self, point, rec)

    monkeypatch.setattr(RunStore, "write_block", hanging)
    monkeypatch.setattr(background, "BACKLOG_NOTE_S", 0.5)
    return stall, release


def _held_by_its_disk(rec) -> bool:
    """The run waits before a point for the storage of the points before (its note said so)."""
    return any(isinstance(e, NoteEvent) and e.kind is NoteKind.STORAGE_WAIT for e in rec.events)


def _ramped_down(sim) -> bool:
    speeds_zero = all(abs(w) < 1e-3 for w in sim.speeds)
    return speeds_zero and (sim.drive(1)["control_word"], sim.drive(2)["control_word"]) == (CW_RAMP_STOP, CW_RAMP_STOP)


THREE_POINTS = small_matrix(spin_rpm=[1000.0, 1500.0, 2000.0])


async def test_a_stop_while_the_run_waits_for_its_disk_before_a_point_ramps_the_drives_down_at_once(
    tmp_path, monkeypatch
):
    """The storage of point 0 never returns; point 1 is measured, then the run waits for point 0
    before point 2, the drives held at point 1's speeds. An operator's stop ramps both drives to
    zero at once, the disk still stalled (a stop never waits for the storage); once the disk is
    back the run ends stopped by that operator with both points kept. The stop waited for the disk."""
    stall, release = _stalled_blocks(monkeypatch)
    async with running(tmp_path, THREE_POINTS) as (sim, eng, rec, run):
        try:
            await wait_for(lambda: rec.blocks_done() >= 2, 60, what="two blocks")
            stall.set()
            await wait_for(lambda: _held_by_its_disk(rec), 40, what="the wait for point 0000's storage")
            eng.request_stop(by="ada")
            await wait_for(lambda: _ramped_down(sim), 20, what="both drives ramped to zero")
            assert not run.done() and eng.state == STOPPING  # the disk still stalls
        finally:
            release.set()
        outcome = await asyncio.wait_for(asyncio.shield(run), 60)
    assert outcome.status == "stopped" and outcome.message.startswith("stopped by ada"), outcome.message
    assert outcome.completed_points == [0, 1]


async def test_an_unattended_run_held_by_its_disk_before_a_point_ramps_its_drives_down_after_the_limit(
    tmp_path, monkeypatch
):
    """Nobody can answer the run (no terminal, no MQTT: [interlocks] unanswered_pause_s 1 s) and
    the storage of point 0 never returns: point 1 is measured, then the run waits for point 0
    before point 2. After the limit it stops: both drives ramp to zero (OFF1) and reach standstill
    while the disk still stalls; once the disk is back the run ends stopped, every point kept.
    The drives were held at point 1's speeds for as long as the disk stalled."""
    stall, release = _stalled_blocks(monkeypatch)
    rig = patient_rig()
    rig = rig.model_copy(update={"interlocks": rig.interlocks.model_copy(update={"unanswered_pause_s": 1.0})})
    async with running(tmp_path, THREE_POINTS, rig) as (sim, eng, rec, run):
        try:
            eng.unattended = True
            await wait_for(lambda: rec.blocks_done() >= 2, 60, what="two blocks")
            stall.set()
            # point 1 is measured first: on a starved machine that took over 40 s
            await wait_for(lambda: _held_by_its_disk(rec), 90, what="the wait for point 0000's storage")
            await wait_for(lambda: _ramped_down(sim), 30, what="both drives ramped to zero")
            assert not run.done() and eng.state == STOPPING  # the disk still stalls: the drives were stopped first
        finally:
            release.set()
        outcome = await asyncio.wait_for(asyncio.shield(run), 60)
    assert outcome.status == "stopped", outcome.message
    assert outcome.message.startswith(
        "stopped by orbitrig (nobody can answer: waiting for complete point 0000 for 1 s, no terminal and no MQTT)"
    ), outcome.message
    assert outcome.completed_points == [0, 1]
