"""An interlock that fails the run (the CAN sensor node gone silent) while a block's write hangs
on a disk that stalls: both drives get the emergency stop and are confirmed at standstill while
the write still hangs (the drives first, the storage second); the run then waits in `stopping`,
its status naming the write it waits for, and ends failed on the interlock once the disk returns,
the hung block stored.

Real parts: the simulator in its own process (its drives over Modbus TCP, its CAN node), the run
engine. Injected (a disk that stalls cannot be produced by the real parts): the block writes hang
on an event once the test sets it going."""

import asyncio
import threading

import pytest

from orbitrig.store.writer import RunStore
from support.rig_configs import interlocked_rig
from support.sweep_helpers import running, small_matrix, wait_for

pytestmark = pytest.mark.timeout(90)

CW_EMERGENCY = 0x047B  # spec control word (OFF3), written out on purpose
LONG = small_matrix(revolutions=50, spin_rpm=[1000.0, 2000.0])  # several seconds at speed-up 40


async def test_an_interlock_trip_stops_the_drives_while_a_write_hangs(tmp_path, monkeypatch):
    stall, back, hung = threading.Event(), threading.Event(), []
    real = RunStore.write_block

    def write_block(self, point, rec):
        if stall.is_set():
            hung.append(rec)
            back.wait(60)  # a disk that does not return until the test lets it
        return real(self, point, rec)

    monkeypatch.setattr(RunStore, "write_block", write_block)
    rig = interlocked_rig(can_heartbeat_timeout_s=1.0)
    async with running(tmp_path, LONG, rig) as (sim, eng, rec, run):
        try:
            await wait_for(lambda: rec.blocks_done() >= 2, what="two blocks")
            stall.set()
            await wait_for(lambda: bool(hung), 30, what="a block write hanging")
            sim.inject("can_node_silent")
            await wait_for(lambda: "waiting for the storage in flight" in eng.message, 30, what="the wait for the disk")
            drives = sim.drive(1), sim.drive(2)
            assert not run.done() and eng.state == "stopping" and hung
            said = eng.message
        finally:
            back.set()
        outcome = await asyncio.wait_for(asyncio.shield(run), 30)
    assert [d["control_word"] for d in drives] == [CW_EMERGENCY, CW_EMERGENCY]
    assert [d["rpm"] for d in drives] == [0, 0] and [d["fault"] for d in drives] == [0, 0]
    assert said.startswith("drives: emergency stop (OFF3); standstill after "), said
    assert "waiting for the storage in flight: store 0000/" in said, said
    assert outcome.status == "failed", outcome.message
    assert "CAN sensor node lost for more than 1 s" in outcome.message, outcome.message
    stored = {p.name for p in (tmp_path / "run" / "points" / "0000").glob("*_???.h5")}
    assert len(stored) >= 2, stored  # the hung block written once the disk returned, with those before
