"""AuxSensors on the python-can virtual bus: against the simulator's CAN node, and
against frames sent here (exact staleness and heartbeat-loss boundaries)."""

from __future__ import annotations

import asyncio
import itertools
import math
import struct

import can
import pytest

from daq.aux import AuxSensors
from daq.errors import DaqError
from sim.rig import SimRig

pytestmark = pytest.mark.timeout(30)
_names = itertools.count()


async def wait_for(pred, timeout=2.0):
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout
    while not pred():
        assert loop.time() < end, "condition not met in time"
        await asyncio.sleep(0.01)


async def test_against_the_simulators_node():
    channel = f"daq-aux-sim-{next(_names)}"
    async with SimRig(speedup=1.0, can_channel=channel) as rig:
        rig.local_control(spin=100.0, orbit=40.0)
        async with AuxSensors(channel, interface="virtual") as aux:
            await wait_for(lambda: aux.latest().ages["p_recess"] < 0.5 and not aux.latest().node_lost, 2.0)
            s, truth = aux.latest(), rig.aux_state()
            assert s.heartbeat_state == 0x05 and s.operational
            for k in ("t_recess", "t_groove", "t_supply"):
                assert getattr(s, k) == pytest.approx(truth[k], abs=0.006)  # 0.01 degC steps
            assert s.flow == pytest.approx(truth["flow"], abs=0.006 / 60000)  # 0.01 L/min steps
            assert s.p_supply == pytest.approx(truth["p_supply"], abs=500)  # 1 kPa steps
            assert s.p_recess == pytest.approx(list(truth["p_recess"]), abs=500)
            assert s.beta == pytest.approx(sum(s.p_recess) / 4 / s.p_supply)
            assert s.beta == pytest.approx(truth["beta"], abs=1e-3)
            assert s.pump_off is bool(truth["pump_off"]) and s.sensor_fault is False
            assert not any(s.stale(k) for k in ("t_recess", "flow", "p_supply", "p_recess", "beta"))

            rig.inject("can_heartbeat_loss")
            await wait_for(lambda: aux.latest().node_lost, 2.5)
            s = aux.latest()
            assert s.heartbeat_age > 1.5 and not s.operational
            assert not s.stale("p_supply")  # process data keep coming: only the heartbeat is gone
            rig.inject("clear")
            await wait_for(lambda: not aux.latest().node_lost, 1.0)

            rig.can_node.silent = True  # the node stops transmitting altogether
            await wait_for(lambda: aux.latest().stale("t_supply"), 1.0)
            assert all(aux.latest().stale(k) for k in ("t_recess", "flow", "p_supply", "p_recess", "beta"))


class FakeClock:
    def __init__(self):
        self.t = 1000.0

    def __call__(self):
        return self.t


async def test_staleness_and_heartbeat_boundaries():
    channel = f"daq-aux-own-{next(_names)}"
    clock = FakeClock()
    tx = can.Bus(interface="virtual", channel=channel)
    try:
        async with AuxSensors(channel, interface="virtual", clock=clock) as aux:
            s = aux.latest()
            assert math.isnan(s.p_supply) and s.stale("p_supply") and s.heartbeat_state is None
            assert not s.node_lost  # counted from opening: 1.5 s not yet over
            clock.t += 1.6
            assert aux.latest().node_lost

            def send(can_id, data):
                tx.send(can.Message(arbitration_id=can_id, data=data, is_extended_id=False))

            n0 = aux.frames_received
            send(0x701, bytes([0x7F]))
            send(0x181, struct.pack("<hhhH", 4012, -550, 2500, 1234))
            send(0x281, struct.pack("<HHHH", 2000, 900, 1000, 1100))
            send(0x381, struct.pack("<HH", 1200, 0x3))
            send(0x182, bytes(8))  # another node's frame: ignored
            send(0x381, bytes(2))  # malformed (too short): counted, ignored
            await wait_for(lambda: aux.frames_received + aux.frames_malformed >= n0 + 5)
            s = aux.latest()
            assert aux.frames_malformed == 1
            assert s.heartbeat_state == 0x7F and not s.node_lost and not s.operational
            assert s.t_recess == pytest.approx(40.12 + 273.15) and s.t_groove == pytest.approx(-5.5 + 273.15)
            assert s.t_supply == pytest.approx(25.0 + 273.15)
            assert s.flow == pytest.approx(12.34 / 60000)
            assert s.p_supply == 2.0e6 and s.p_recess == (0.9e6, 1.0e6, 1.1e6, 1.2e6)
            assert s.beta == pytest.approx(1.05e6 / 2.0e6)
            assert s.sensor_fault and s.pump_off

            clock.t += 0.49
            s = aux.latest()
            assert not s.stale("p_supply") and not s.stale("t_recess") and s.ages["flow"] == pytest.approx(0.49)
            clock.t += 0.02
            assert aux.latest().stale("p_supply") and aux.latest().stale("beta")
            assert not aux.latest().node_lost
            clock.t += 0.98  # 1.49 s after the heartbeat
            assert not aux.latest().node_lost
            clock.t += 0.02
            assert aux.latest().node_lost
            send(0x701, bytes([0x05]))
            await wait_for(lambda: not aux.latest().node_lost)
            assert aux.latest().operational
    finally:
        tx.shutdown()


async def test_another_nodes_heartbeat_is_named_but_never_read_as_the_nodes():
    """Every node's heartbeat passes the bus filter (0x700 mask 0x780): another node's (0x702, 0x77F)
    names that node while node 1 has sent none, and counts as none of node 1's frames (no heartbeat
    state, no arrival, the node lost all the same); forgotten 1.5 s after its last; once node 1 is
    heard, no other node is named (a bus it shares with them)."""
    channel = f"daq-aux-others-{next(_names)}"
    clock = FakeClock()
    tx = can.Bus(interface="virtual", channel=channel)
    try:
        async with AuxSensors(channel, interface="virtual", clock=clock) as aux:

            def send(can_id, data):
                tx.send(can.Message(arbitration_id=can_id, data=data, is_extended_id=False))

            arrived = aux.arrival
            clock.t += 1.6
            send(0x702, bytes([0x05]))
            send(0x77F, bytes(2))  # another node's, of any length: not ours to judge
            send(0x700, bytes([0x05]))  # no node 0
            await wait_for(lambda: aux.latest().other_nodes == (2, 127))
            await asyncio.sleep(0.05)
            s = aux.latest()
            assert s.node_lost and s.heartbeat_state is None and math.isinf(s.heartbeat_age)
            assert (aux.frames_received, aux.frames_malformed) == (0, 0)
            assert not arrived.is_set() and aux.arrival is arrived
            assert s.others_heard == (
                "; heartbeats 0x702, 0x77F heard (nodes 2, 127), not node 1's 0x701 ([transports] can_node_id 1)"
            )
            clock.t += 1.51
            assert aux.latest().other_nodes == () and aux.latest().others_heard == ""
            send(0x702, bytes([0x05]))
            send(0x701, bytes([0x05]))
            await wait_for(lambda: not aux.latest().node_lost and aux.latest().other_nodes == (2,))
            assert aux.latest().operational and aux.latest().others_heard == ""
    finally:
        tx.shutdown()


async def test_each_frame_read_sets_the_arrival_taken_before_it():
    """`arrival`: set by the next frame read (its values already in `latest()`), then a new one:
    the pressure check wakes as a frame arrives instead of looking every few ms. A frame that is
    not read (malformed, another node's) sets nothing."""
    channel = f"daq-aux-arrival-{next(_names)}"
    tx = can.Bus(interface="virtual", channel=channel)
    try:
        async with AuxSensors(channel, interface="virtual") as aux:

            def send(can_id, data):
                tx.send(can.Message(arbitration_id=can_id, data=data, is_extended_id=False))

            arrived = aux.arrival
            send(0x182, bytes(8))  # another node's
            send(0x281, bytes(2))  # malformed
            await wait_for(lambda: aux.frames_malformed == 1)
            await asyncio.sleep(0.05)
            assert not arrived.is_set() and aux.arrival is arrived
            send(0x281, struct.pack("<HHHH", 2000, 900, 1000, 1100))
            await asyncio.wait_for(arrived.wait(), 2.0)
            assert aux.latest().p_supply == 2.0e6  # read before the event was set
            assert aux.arrival is not arrived and not aux.arrival.is_set()
    finally:
        tx.shutdown()


async def test_unknown_interface_is_a_daq_error():
    with pytest.raises(DaqError, match="CAN nosuchbus:x: cannot open bus"):
        async with AuxSensors("x", interface="nosuchbus"):
            pass


async def test_a_cancel_arriving_with_the_heartbeat_ends_the_wait_for_it():
    """`heard()` cancelled in the loop turn the node's heartbeat is read (a Ctrl-C of the preflight
    as the node answers): the cancel is raised, not dropped as the wait returns (asyncio.wait_for
    of Python 3.11 took such a cancel and returned). The frame is handed to the reader's own
    handler in that turn: a real bus cannot be made to deliver it in a chosen turn."""
    channel = f"daq-aux-heard-cancel-{next(_names)}"
    async with AuxSensors(channel, interface="virtual") as aux:
        task = asyncio.ensure_future(aux.heard(within=2.0))
        await asyncio.sleep(0.05)  # waiting for the heartbeat
        aux._on_message(can.Message(arbitration_id=0x701, data=bytes([5]), is_extended_id=False))
        task.cancel()
        done, _ = await asyncio.wait([task], timeout=1.0)
        assert done and task.cancelled()
