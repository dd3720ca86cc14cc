"""The simulator's CAN sensor node as node 5 ([can] node_id, `python -m sim --can-node-id`), read by a
rig whose [transports] can_node_id is 5, end to end: a sweep and a calibration step run on its frames
0x185, 0x285, 0x385 and heartbeat 0x705 (none of node 1's on the bus), and the node lost mid-run is
named by its heartbeat 0x705. A rig that reads node 5 while the node answers as node 1 fails the run
after can_heartbeat_timeout_s, both drives given the emergency stop first, with a message naming the
heartbeat expected (0x705) and the one heard (0x701, node 1).

Real parts: the simulator in this process behind its real Modbus server, its CAN node on python-can's
`virtual` bus (no SocketCAN in every kernel), read by daq.aux.AuxSensors; a second node on the bus
lists the CAN ids sent."""

from __future__ import annotations

import asyncio
import contextlib
import re
import time
from collections.abc import AsyncIterator

import can
import pytest

from orbitrig.cli.simulated_rig import simulated_access
from orbitrig.config import MPA, RPM, RigConfig, load_rig
from orbitrig.run.calibration import CalibrationSession, SlowRoll
from orbitrig.run.calibration_checks import CalibrationFailed
from orbitrig.run.engine import RunEngine
from support.sweep_helpers import Recorder, small_matrix, wait_for

pytestmark = pytest.mark.timeout(120)

NODE = 5
NODE_5_IDS = {0x185, 0x285, 0x385, 0x705}
CW_EMERGENCY = 0x047B  # spec control word (OFF3), written out on purpose
LONG = small_matrix(revolutions=50, spin_rpm=[1000.0, 2000.0])  # several seconds at speed-up 40
ROLL = SlowRoll(spin=600 * RPM, recess_pressure=0.4826 * MPA, pressure_ratio=0.25, revolutions=5)


def _rig(node_id: int = NODE, limit_s: float | None = None) -> RigConfig:
    """The shipped rig.toml reading CAN node `node_id`; `limit_s`: its can_heartbeat_timeout_s."""
    rig = load_rig()
    rig = rig.model_copy(update={"transports": rig.transports.model_copy(update={"can_node_id": node_id})})
    if limit_s is None:
        return rig
    quick = {"can_heartbeat_timeout_s": limit_s}
    return rig.model_copy(update={"interlocks": rig.interlocks.model_copy(update=quick)})


@contextlib.asynccontextmanager
async def _simulator(node_id: int) -> AsyncIterator[tuple[object, set[int]]]:
    """The simulator in this process, its CAN node `node_id`, and the CAN ids a node of the test's own
    reads on its bus meanwhile."""
    from sim.rig import SimRig

    async with SimRig(speedup=40, adc_pty=False, can_node_id=node_id) as sim_rig:
        assert sim_rig.endpoints()["can_node_id"] == node_id
        seen: set[int] = set()
        bus = can.Bus(interface="virtual", channel=sim_rig.can_channel)

        async def listen() -> None:
            while True:
                msg = bus.recv(0.0)
                if msg is None:
                    await asyncio.sleep(0.05)
                else:
                    seen.add(msg.arbitration_id)

        listening = asyncio.create_task(listen())
        try:
            yield sim_rig, seen
        finally:
            listening.cancel()
            await asyncio.gather(listening, return_exceptions=True)
            bus.shutdown()


def _control_words(sim_rig) -> tuple[int, int]:
    return sim_rig.drives[1].read(0, 1)[0], sim_rig.drives[2].read(0, 1)[0]


async def test_a_sweep_runs_on_node_5_and_a_node_lost_mid_run_is_named_0x705(tmp_path):
    async with _simulator(NODE) as (sim_rig, seen):
        eng = RunEngine(_rig(), out_dir=tmp_path / "whole", access=simulated_access(sim_rig), confirm_mode="auto")
        outcome = await asyncio.wait_for(eng.run(small_matrix()), 60)
        assert outcome.status == "completed", outcome.message
        assert seen == NODE_5_IDS, sorted(map(hex, seen))  # node 5's frames alone: none of node 1's

        access = simulated_access(sim_rig)
        eng = RunEngine(_rig(limit_s=1.0), out_dir=tmp_path / "lost", access=access, confirm_mode="auto")
        rec = Recorder()
        eng.subscribe(rec)
        run = asyncio.create_task(eng.run(LONG))
        await wait_for(lambda: rec.blocks_done() >= 2, what="two blocks")
        sim_rig.inject("can_node_silent")
        outcome = await asyncio.wait_for(run, 30)
        words = _control_words(sim_rig)
    assert outcome.status == "failed", outcome.message
    assert "CAN sensor node lost for more than 1 s (silent: no heartbeat 0x705 and no process data" in outcome.message
    assert "0x701" not in outcome.message, outcome.message
    assert words == (CW_EMERGENCY, CW_EMERGENCY)


async def test_a_node_answering_as_another_id_fails_the_run_naming_both_drives_stopped_first(tmp_path):
    """rig.toml reads node 5, the node answers as node 1: nothing of node 5 is read; the run is
    suspended (the node lost), then fails after can_heartbeat_timeout_s with the ids expected and heard."""
    async with _simulator(1) as (sim_rig, seen):
        access = simulated_access(sim_rig)
        eng = RunEngine(_rig(limit_s=1.0), out_dir=tmp_path / "run", access=access, confirm_mode="auto")
        t0 = time.monotonic()
        outcome = await asyncio.wait_for(eng.run(small_matrix()), 60)
        took = time.monotonic() - t0
        words = _control_words(sim_rig)
        speeds = sim_rig.speeds
    assert outcome.status == "failed", outcome.message
    assert outcome.message.startswith("interlock: CAN sensor node lost for more than 1 s"), outcome.message
    assert (
        "silent: no frame from node 5 (heartbeat 0x705) since the bus was opened; heartbeat 0x701 heard "
        "(node 1), not node 5's 0x705 ([transports] can_node_id 5)"
    ) in outcome.message, outcome.message
    assert 0x701 in seen and not seen & NODE_5_IDS, sorted(map(hex, seen))
    assert took < 20.0, took  # 1.5 s until the node counts as lost, then 1 s; margin for load
    assert words == (CW_EMERGENCY, CW_EMERGENCY) and speeds == (0.0, 0.0), (words, speeds)
    log = (tmp_path / "run" / "run.log").read_text().splitlines()
    stop = next(i for i, line in enumerate(log) if "emergency stop" in line)
    assert stop < len(log) - 1 and outcome.message in log[-1], log[-6:]  # the stop before the end's line


async def test_a_calibration_step_runs_on_node_5_and_names_0x705_when_the_node_is_lost():
    notes: list[str] = []
    async with _simulator(NODE) as (sim_rig, seen):
        session = CalibrationSession(_rig(limit_s=1.0), simulated_access(sim_rig), notes.append)
        with pytest.raises(CalibrationFailed) as failed:
            async with session:
                await session.roll(ROLL)
                block = await session.average(5)
                assert block.record_phasors.shape[0] == 5 and session.io.open_aux.latest().operational
                sim_rig.inject("can_heartbeat_loss", on=True)
                await session.watched(lambda: asyncio.sleep(30.0))
        words = _control_words(sim_rig)
    assert seen == NODE_5_IDS, sorted(map(hex, seen))
    said = str(failed.value)
    # said silent if a loaded host held every frame of the node 0.5 s at that moment
    lost = r"(silent: )?no heartbeat 0x705 (for 1\.5 s|and no process data for [\d.]+ s)"
    assert re.match(rf"interlock: CAN sensor node lost \({lost}\) during the slow roll", said), said
    assert "0x701" not in said, said
    assert words == (CW_EMERGENCY, CW_EMERGENCY)
    assert "both drives stopped" in notes, notes
