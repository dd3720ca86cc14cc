"""The CAN sensor node gone silent mid-run (the simulator's can_node_silent: no heartbeat, no
process data): the run is suspended, then fails after [interlocks] can_heartbeat_timeout_s with
both drives given the emergency stop first, a message naming the CAN node and its silence, and
the blocks stored before kept. A node back within the limit lets the run complete."""

import asyncio
import re
import time

import pytest

from support.rig_configs import interlocked_rig
from support.sweep_helpers import running, small_matrix, wait_for

pytestmark = pytest.mark.timeout(90)

CW_EMERGENCY = 0x047B  # spec control word (OFF3), written out on purpose
LONG = small_matrix(revolutions=50, spin_rpm=[1000.0, 2000.0])  # several seconds at speed-up 40


async def test_a_silent_can_node_fails_the_run_after_its_timeout_drives_stopped_first(tmp_path):
    rig = interlocked_rig(can_heartbeat_timeout_s=1.0)
    async with running(tmp_path, LONG, rig) as (sim, eng, rec, run):
        await wait_for(lambda: rec.blocks_done() >= 2, what="two blocks")
        measured, t0 = rec.blocks_done() - 1, time.monotonic()  # blocks started, less the one under way
        sim.inject("can_node_silent")
        outcome = await asyncio.wait_for(asyncio.shield(run), 30)
        took = time.monotonic() - t0
        drives = sim.drive(1), sim.drive(2)
    assert outcome.status == "failed", outcome.message
    assert "CAN sensor node lost for more than 1 s" in outcome.message, outcome.message
    assert re.search(r"\(silent: no heartbeat 0x701 and no process data for \d+\.\d s\)", outcome.message), (
        outcome.message
    )
    assert 2.0 < took < 10.0, took  # 1.5 s until the node counts as lost, then 1 s; margin for load
    assert [d["control_word"] for d in drives] == [CW_EMERGENCY, CW_EMERGENCY]
    assert [d["rpm"] for d in drives] == [0, 0] and [d["fault"] for d in drives] == [0, 0]
    assert len(list((tmp_path / "run" / "points" / "0000").glob("*_???.h5"))) >= measured >= 1
    log = (tmp_path / "run" / "run.log").read_text().splitlines()
    said = [i for i, line in enumerate(log) if "CAN sensor node" in line]
    assert said and "suspended" in log[said[0]], log[-12:]  # the suspension is said first
    stop = next(i for i, line in enumerate(log) if "emergency stop" in line and i > said[0])
    assert stop < len(log) - 1 and outcome.message in log[-1], log[-6:]  # the stop before the end's line


async def test_a_can_node_back_within_its_limit_lets_the_run_complete(tmp_path):
    async with running(tmp_path, LONG) as (sim, eng, rec, run):  # the shipped limit: 10 s
        await wait_for(lambda: rec.blocks_done() >= 2, what="two blocks")
        sim.inject("can_node_silent")
        await wait_for(lambda: eng.state == "paused", 10, what="the suspension")
        sim.inject("clear")
        outcome = await asyncio.wait_for(asyncio.shield(run), 60)
    assert outcome.status == "completed", outcome.message
    log = (tmp_path / "run" / "run.log").read_text()
    assert re.search(
        r"\[paused\] suspended by interlock: CAN sensor node lost \(silent: no heartbeat 0x701 and no process data", log
    ), log
    assert "interlock cleared (can_heartbeat): settling and acquiring the block again" in log
