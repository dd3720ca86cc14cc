"""The lubricant supply interlock on the real simulator: the supply pump off or the supply below
its minimum is watched whenever a drive turns (the operator's manual settings too) and fails the
run after [interlocks] supply_lost_timeout_s; a CAN node that keeps its heartbeat but is not
operational, sends no pressure or status frames or reports a faulty sensor counts as a lost node
(fails after can_heartbeat_timeout_s). Checked on the simulator's drive registers."""

import asyncio
import contextlib
import dataclasses
import math
import struct
import time

import can
import pytest

from daq.aux import AuxState
from drives.drive import DriveStatus
from drives.state import RigDriveState
from orbitrig import config as cfg
from orbitrig.run import interlocks
from support.rig_configs import interlocked_rig
from support.sweep_helpers import Recorder, SimulatorView, small_matrix, wait_for

pytestmark = pytest.mark.timeout(90)

CW_EMERGENCY = 0x047B  # spec control word (OFF3), written out on purpose
LONG = small_matrix(revolutions=50, spin_rpm=[1000.0, 2000.0])  # several seconds at speed-up 40
# two points that differ in static eccentricity: the drives keep turning while it is set by hand
TWO_MANUAL = small_matrix(static_eccentricity=[0.15, 0.0])


def _standstill(sim) -> bool:
    return sim.drive(1)["rpm"] == 0 and sim.drive(2)["rpm"] == 0


def _failed_and_stopped(outcome, sim, *expected: str) -> None:
    assert outcome.status == "failed", outcome.message
    for text in expected:
        assert text in outcome.message, outcome.message
    assert (sim.drive(1)["control_word"], sim.drive(2)["control_word"]) == (CW_EMERGENCY, CW_EMERGENCY)
    assert _standstill(sim)


class StandInNode:
    """The sensor node on an in-process virtual bus, sending what the simulator's node sends for the
    demo matrix's settings (recess 0.4826 MPa, beta 0.4), every 100 ms, heartbeat every 500 ms; it
    can go pre-operational, drop its status frame or flag a faulty sensor, which the simulator's
    node cannot."""

    def __init__(self, channel: str):
        self.bus = can.Bus(interface="virtual", channel=channel)
        self.heartbeat, self.pressures, self.status, self.sensor_fault = 0x05, True, True, False

    async def run(self) -> None:
        pr, ps = 483, 1207  # kPa
        for k in range(10**9):
            frames = [(0x181, struct.pack("<hhhH", 4000, 4000, 4000, 200))] if self.pressures else []
            if self.pressures:
                frames.append((0x281, struct.pack("<HHHH", ps, pr, pr, pr)))
            if self.status:
                frames.append((0x381, struct.pack("<HH", pr, int(self.sensor_fault))))
            if k % 5 == 0:
                frames.append((0x701, bytes([self.heartbeat])))
            for can_id, data in frames:
                self.bus.send(can.Message(arbitration_id=can_id, data=data, is_extended_id=False))
            await asyncio.sleep(0.1)


@contextlib.asynccontextmanager
async def _running(tmp_path, matrix, rig, *, node: bool = False, confirm_mode: str = "auto"):
    """The simulator (own process) and a RunEngine on it, the CAN node optionally a `StandInNode`:
    yields (SimulatorView, engine, recorder, run task, node or None)."""
    from orbitrig.cli.simulated_rig import simulated_rig
    from orbitrig.run.engine import RunEngine

    async with simulated_rig(40.0) as (sim, access):
        stand_in, feeder = None, None
        if node:
            channel = f"stand-in-{tmp_path.name}"
            stand_in = StandInNode(channel)
            feeder = asyncio.create_task(stand_in.run())
            ends = dataclasses.replace(access.endpoints, can_channel=channel, can_interface="virtual")
            access = dataclasses.replace(access, endpoints=ends)
        eng = RunEngine(rig, out_dir=tmp_path / "run", access=access, confirm_mode=confirm_mode)
        rec = Recorder()
        eng.subscribe(rec)
        run = asyncio.create_task(eng.run(matrix))
        view = SimulatorView(sim)
        try:
            yield view, eng, rec, run, stand_in
        finally:
            for task in (run, feeder):
                if task is not None and not task.done():
                    task.cancel()
                    await asyncio.gather(task, return_exceptions=True)
            if stand_in is not None:
                stand_in.bus.shutdown()
            view.freeze()


def _preoperational(node: StandInNode) -> None:  # a node that reset: heartbeat 0x7F, no process data
    node.heartbeat, node.pressures, node.status = 0x7F, False, False


def _status_frame_gone(node: StandInNode) -> None:
    node.status = False


def _sensor_fault(node: StandInNode) -> None:
    node.sensor_fault = True


@pytest.mark.parametrize(
    "fault, named",
    [
        (_preoperational, "CAN sensor node not operational (heartbeat 0x701 state 0x7f)"),
        (_status_frame_gone, "CAN sensor node sends no status frame 0x381"),
        (_sensor_fault, "faulty sensor (status 0x381 bit 0)"),
    ],
    ids=["pre-operational", "no-status-frame", "sensor-fault"],
)
async def test_a_node_with_a_heartbeat_but_no_usable_data_fails_the_run(tmp_path, fault, named):
    rig = interlocked_rig(can_heartbeat_timeout_s=1.0)
    async with _running(tmp_path, LONG, rig, node=True) as (sim, eng, rec, run, node):
        await wait_for(lambda: rec.blocks_done() >= 2, what="two blocks")
        t0 = time.monotonic()
        fault(node)
        await wait_for(lambda: eng.state == "paused", timeout=5, what="the suspension")
        assert "suspended by interlock: supply pressure and pump not watched" in eng.message, eng.message
        outcome = await asyncio.wait_for(run, 20)
        took = time.monotonic() - t0
    _failed_and_stopped(outcome, sim, named, "for more than 1 s")
    # 1.5 s until the frames count as missing, then 1 s; generous margin for a loaded machine
    assert 1.0 < took < 8.0, took


async def test_the_pump_stopping_while_the_operator_sets_a_point_fails_the_run(tmp_path):
    rig = interlocked_rig(supply_lost_timeout_s=1.0)
    async with _running(tmp_path, TWO_MANUAL, rig, confirm_mode="remote") as (sim, eng, rec, run, _):
        first = None
        while True:  # confirm everything up to the second point's manual settings
            await wait_for(lambda: eng.waiting_step is not None or run.done(), what="a confirmation")
            step = eng.waiting_step
            assert step is not None, run.result().message
            if step.startswith("manual:") and first is not None and step != first:
                break
            first = first or step
            eng.confirm(step)
        assert not _standstill(sim)  # the spindles turn while the static eccentricity is set
        t0 = time.monotonic()
        sim.set_manual(recess_pressure=0.0)  # the node reports the pump off and 0 MPa supply
        outcome = await asyncio.wait_for(run, 20)
        took = time.monotonic() - t0
    _failed_and_stopped(outcome, sim, "lubricant supply pump is off for more than 1 s")
    assert 1.0 < took < 8.0, took


async def test_the_pump_stopping_during_a_block_fails_the_run_after_its_limit(tmp_path):
    rig = interlocked_rig(supply_lost_timeout_s=1.0)  # suspend_timeout_s stays 300 s
    async with _running(tmp_path, LONG, rig) as (sim, eng, rec, run, _):
        await wait_for(lambda: rec.blocks_done() >= 2, what="two blocks")
        t0 = time.monotonic()
        sim.set_manual(recess_pressure=0.0)
        await wait_for(lambda: eng.state == "paused", timeout=5, what="the suspension")
        # the node sends pressure (0x281) and pump status (0x381) in separate frames: either trips first
        first_reason = ("lubricant supply pump is off", "supply pressure 0.000 MPa outside the band")
        assert any(f"suspended by interlock: {why}" in eng.message for why in first_reason), eng.message
        outcome = await asyncio.wait_for(run, 20)
        took = time.monotonic() - t0
    _failed_and_stopped(outcome, sim, "lubricant supply pump is off for more than 1 s")
    assert 1.0 < took < 8.0, took
    (log,) = (tmp_path / "run").rglob("run.log")  # the pump is named whichever frame tripped first
    assert "suspended by interlock: lubricant supply pump is off" in log.read_text()


# ------------------------------------------------------------------ check() alone (pure)
CFG = cfg.load_rig().interlocks  # band 0.2..8 MPa


def _aux(**values) -> AuxState:
    fresh = {name: 0.1 for name in ("p_supply", "pump_off", "sensor_fault", "p_recess")}
    base = dict(p_supply=1.2e6, heartbeat_state=0x05, heartbeat_age=0.1, node_lost=False, ages=fresh)
    return AuxState(**(base | values))


def _drives(rpm: float) -> RigDriveState:
    raw = round(rpm)
    rad_s = rpm * 2 * math.pi / 60
    spin, orbit = (
        DriveStatus(n, i, 0x047F, rad_s, 0, rad_s, 0.0, 0, 1.0, raw, raw) for n, i in (("spin", 1), ("orbit", 2))
    )
    return RigDriveState(spin, orbit, link_ok=True)


def _kinds(aux: AuxState, rpm: float, armed: bool) -> list[str]:
    return [t.kind for t in interlocks.check(aux, _drives(rpm), CFG, pressure_armed=armed)]


def test_the_supply_is_watched_while_a_drive_turns_the_band_top_once_armed():
    off = _aux(pump_off=True, p_supply=0.0)
    assert _kinds(off, 0.0, armed=False) == []  # at standstill before the point's pressures are verified
    assert _kinds(off, 1000.0, armed=False) == ["supply_pump", "supply_low"]
    assert _kinds(_aux(p_supply=9.7e6), 1000.0, armed=False) == []  # the operator may be adjusting it
    assert _kinds(_aux(p_supply=9.7e6), 1000.0, armed=True) == ["supply_pressure"]
    stale = _aux(ages={"p_supply": 3.0, "pump_off": 3.0}, heartbeat_state=0x05)
    (trip,) = interlocks.check(stale, _drives(1000.0), CFG, pressure_armed=True)
    assert trip.kind == "can_node" and trip.action == interlocks.SUSPEND
    assert (
        trip.message
        == "supply pressure and pump not watched: CAN sensor node sends no pressure frame 0x281 (last 3.0 s ago)"
    )


def test_a_lost_node_is_said_silent_when_its_process_data_stopped_too():
    def said(aux: AuxState) -> str:
        (trip,) = interlocks.check(aux, _drives(1000.0), CFG, pressure_armed=True)
        return trip.message

    hb_only = _aux(node_lost=True, heartbeat_age=1.6)  # process data 0.1 s old
    silent = _aux(node_lost=True, heartbeat_age=1.6, ages={"p_supply": 1.6, "pump_off": 1.6, "t_recess": 1.6})
    assert said(hb_only) == "CAN sensor node lost (no heartbeat 0x701 for 1.5 s)"
    assert said(silent) == "CAN sensor node lost (silent: no heartbeat 0x701 and no process data for 1.6 s)"
    one_fresh = _aux(node_lost=True, heartbeat_age=1.6, ages={"p_supply": 1.6, "t_recess": 0.4})
    assert said(one_fresh) == "CAN sensor node lost (no heartbeat 0x701 for 1.5 s)"
    never = _aux(node_lost=True, heartbeat_age=math.inf, ages={"p_supply": math.inf, "t_recess": 2.0})
    assert said(never) == "CAN sensor node lost (silent: no heartbeat 0x701 and no process data for 2.0 s)"
    unheard = _aux(node_lost=True, heartbeat_age=math.inf, ages={"p_supply": math.inf})
    assert (
        said(unheard)
        == "CAN sensor node lost (silent: no frame from node 1 (heartbeat 0x701) since the bus was opened)"
    )
    other = _aux(node_lost=True, heartbeat_age=math.inf, ages={}, node_id=5, other_nodes=(1,))  # node 1 answers
    assert said(other) == (
        "CAN sensor node lost (silent: no frame from node 5 (heartbeat 0x705) since the bus was opened; "
        "heartbeat 0x701 heard (node 1), not node 5's 0x705 ([transports] can_node_id 5))"
    )
    # node 5 was heard, then lost, on a bus node 1 shares: node 1 is no other id answering instead
    shared = _aux(node_lost=True, heartbeat_age=1.6, node_id=5, other_nodes=(1,))
    assert said(shared) == "CAN sensor node lost (no heartbeat 0x705 for 1.5 s)"


def test_a_node_lost_past_its_limit_says_why_it_was_lost():
    """The fail after the limit keeps the trip's reason: no heartbeat, or the bus link failed."""
    from orbitrig.run.supervision import _lasting

    for why in (
        "no heartbeat 0x701 for 1.5 s",
        "silent: no heartbeat 0x701 and no process data for 1.2 s",
        "its bus link failed: DaqError: cannot open bus (refused)",
    ):
        trip = interlocks.Trip(interlocks.TripKind.CAN_HEARTBEAT, interlocks.SUSPEND, f"CAN sensor node lost ({why})")
        assert _lasting(trip, 10.0) == (
            f"CAN sensor node lost for more than 10 s ({why}): supply pressure and pump are not watched"
        )
