"""Waits that end on their own, on the real simulator: a lost CAN heartbeat fails the run after
[interlocks] can_heartbeat_timeout_s, a pause nobody can answer stops it after unanswered_pause_s,
and an abort during the closing ramp turns it into an emergency stop. Checked on the simulator's
drive registers (what the drives were commanded)."""

import asyncio
import time

import pytest

from support.rig_configs import interlocked_rig
from support.sweep_helpers import running, small_matrix, wait_for

pytestmark = pytest.mark.timeout(90)

# Spec control words, written out here (not imported from drives/) on purpose.
CW_RAMP_STOP, CW_EMERGENCY = 0x047E, 0x047B


LONG = small_matrix(revolutions=50, spin_rpm=[1000.0, 2000.0])  # several seconds at speed-up 40


def _commanded(sim) -> tuple[int, int]:
    """The control words the drives hold (spin, orbit)."""
    return sim.drive(1)["control_word"], sim.drive(2)["control_word"]


def _faults(sim) -> tuple[int, int]:
    return sim.drive(1)["fault"], sim.drive(2)["fault"]


def _standstill(sim) -> bool:
    """Both drive models at zero speed now."""
    return sim.drive(1)["rpm"] == 0 and sim.drive(2)["rpm"] == 0


@pytest.mark.parametrize("paused", [False, True], ids=["running", "paused-by-the-operator"])
async def test_a_lost_can_heartbeat_fails_the_run_within_its_timeout(tmp_path, paused):
    rig = interlocked_rig(can_heartbeat_timeout_s=1.0)
    async with running(tmp_path, LONG, rig) as (sim, eng, rec, run):
        await wait_for(lambda: rec.blocks_done() >= 2, what="two blocks")
        if paused:  # a safe point, no interlock hold: the supervisor's own clock still runs
            eng.request_pause()
            await wait_for(lambda: eng.state == "paused", what="the pause")
        t0 = time.monotonic()
        sim.inject("can_heartbeat_loss", on=True)
        outcome = await asyncio.wait_for(run, 20)
        took = time.monotonic() - t0
    assert outcome.status == "failed", outcome.message
    assert "CAN sensor node lost for more than 1 s" in outcome.message
    # 1.5 s until the node counts as lost, then 1 s; generous margin for a loaded machine
    assert 2.0 < took < 10.0, took
    assert _commanded(sim) == (CW_EMERGENCY, CW_EMERGENCY)
    assert _faults(sim) == (0, 0) and _standstill(sim)


def _stopped_unanswered(outcome, took: float, rec, sim) -> None:
    """A pause nobody could answer (limit 1 s) stopped the run `took` s after the limit began:
    a ramp stop of both drives, to standstill, without a fault."""
    assert outcome.status == "stopped", outcome.message
    assert 0.9 < took < 8.0, took
    assert any("nobody can answer (paused for 1 s" in e.message for e in rec.events if hasattr(e, "state"))
    assert _commanded(sim) == (CW_RAMP_STOP, CW_RAMP_STOP)
    assert _faults(sim) == (0, 0) and _standstill(sim)


async def test_a_pause_nobody_can_answer_stops_the_run(tmp_path):
    rig = interlocked_rig(unanswered_pause_s=1.0)
    async with running(tmp_path, small_matrix(revolutions=30), rig) as (sim, eng, rec, run):
        eng.unattended = True
        await wait_for(lambda: rec.blocks_done() >= 2, what="two blocks")
        eng.request_pause()
        await wait_for(lambda: eng.state == "paused", what="the pause")
        t0 = time.monotonic()
        outcome = await asyncio.wait_for(run, 20)
        took = time.monotonic() - t0
    _stopped_unanswered(outcome, took, rec, sim)


async def test_a_pause_under_way_when_nobody_can_answer_any_more_stops_after_the_limit(tmp_path):
    """`serve` losing its broker marks the run unattended while a pause is already held: that
    pause, begun with no limit, stops the run unanswered_pause_s after the mark, not at once."""
    rig = interlocked_rig(unanswered_pause_s=1.0)
    async with running(tmp_path, small_matrix(revolutions=30), rig) as (sim, eng, rec, run):
        await wait_for(lambda: rec.blocks_done() >= 2, what="two blocks")
        eng.request_pause()
        await wait_for(lambda: eng.state == "paused", what="the pause")
        await asyncio.sleep(1.5)  # longer than the limit: counted from the mark, not from the pause
        assert eng.state == "paused" and not run.done()
        t0 = time.monotonic()
        eng.unattended = True
        outcome = await asyncio.wait_for(run, 20)
        took = time.monotonic() - t0
    _stopped_unanswered(outcome, took, rec, sim)


async def test_a_confirmation_nobody_can_answer_stops_the_run(tmp_path):
    rig = interlocked_rig(unanswered_pause_s=1.0)
    async with running(tmp_path, small_matrix(), rig, confirm_mode="remote") as (sim, eng, rec, run):
        eng.unattended = True
        await wait_for(lambda: eng.state == "waiting", what="waiting for the manual settings")
        outcome = await asyncio.wait_for(run, 20)
    assert outcome.status == "stopped" and eng.state == "idle", outcome.message
    assert _faults(sim) == (0, 0) and _standstill(sim)


async def test_without_unattended_a_pause_holds(tmp_path):
    rig = interlocked_rig(unanswered_pause_s=1.0)
    async with running(tmp_path, small_matrix(revolutions=30), rig) as (sim, eng, rec, run):
        await wait_for(lambda: rec.blocks_done() >= 2, what="two blocks")
        eng.request_pause()
        await wait_for(lambda: eng.state == "paused", what="the pause")
        await asyncio.sleep(2.0)
        assert eng.state == "paused" and not run.done()
        eng.request_resume()
        outcome = await asyncio.wait_for(run, 30)
    assert outcome.status == "completed", outcome.message


async def test_an_abort_during_the_closing_ramp_becomes_an_emergency_stop(tmp_path):
    # speed-up 1: the ramp from 1000 rpm takes seconds, long enough to abort in the middle of it
    async with running(tmp_path, small_matrix(), speedup=1.0) as (sim, eng, rec, run):
        await wait_for(lambda: sim.speeds[0] > 0.9 * 1000 * 2 * 3.14159 / 60, timeout=30, what="spin at speed")
        eng.request_stop_now("SIGTERM")
        await wait_for(lambda: _commanded(sim) == (CW_RAMP_STOP, CW_RAMP_STOP), timeout=10, what="ramp stop")
        assert not _standstill(sim)
        eng.request_abort()
        outcome = await asyncio.wait_for(run, 20)
    assert outcome.status == "aborted" and "while stopping" in outcome.message, outcome.message
    assert _commanded(sim) == (CW_EMERGENCY, CW_EMERGENCY)
    assert _standstill(sim)
    assert "drives: emergency stop (OFF3) after an abort during the ramp" in (tmp_path / "run" / "run.log").read_text()
