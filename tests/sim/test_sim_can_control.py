"""The CAN sensor node (read off the virtual bus, decoded per docs/protocols/can-node.md)
and the JSON-lines control API."""

from __future__ import annotations

import asyncio
import json
import math
import struct
import uuid

import can
import numpy as np
import pytest

from sim.config import SimConfig
from sim.rig import SimRig


async def collect(bus: can.BusABC, seconds: float) -> list[can.Message]:
    out = []
    end = asyncio.get_running_loop().time() + seconds
    while asyncio.get_running_loop().time() < end:
        msg = bus.recv(0)
        if msg is None:
            await asyncio.sleep(0.005)
        else:
            out.append(msg)
    return out


async def test_can_node_frames_periods_and_values():
    channel = f"sim-test-{uuid.uuid4().hex[:8]}"
    bus = can.Bus(interface="virtual", channel=channel)
    try:
        async with SimRig(SimConfig(), speedup=5.0, can_channel=channel) as rig:
            rig.local_control(spin=250.0, orbit=60.0)
            rig.set_manual(recess_pressure=1.2e6, pressure_ratio=0.6)
            await asyncio.sleep(0.05)
            msgs = await collect(bus, 1.25)
            state = rig.aux_state()
    finally:
        bus.shutdown()
    by_id: dict[int, list[can.Message]] = {}
    for m in msgs:
        assert not m.is_extended_id
        by_id.setdefault(m.arbitration_id, []).append(m)
    assert set(by_id) == {0x181, 0x281, 0x381, 0x701}
    assert {len(m.data) for m in by_id[0x181] + by_id[0x281]} == {8}
    assert {len(m.data) for m in by_id[0x381]} == {4}
    assert all(bytes(m.data) == b"\x05" for m in by_id[0x701])  # operational
    assert 11 <= len(by_id[0x181]) <= 14 and 2 <= len(by_id[0x701]) <= 4
    for can_id, period, tol in ((0x181, 0.1, 0.02), (0x701, 0.5, 0.06)):  # the heartbeat: 1 to 3 intervals
        dt = np.diff([m.timestamp for m in by_id[can_id]])
        assert np.mean(dt) == pytest.approx(period, abs=tol)
    t_rec, t_groove, t_sup, flow = struct.unpack("<hhhH", by_id[0x181][-1].data)
    p_sup, p1, p2, p3 = struct.unpack("<HHHH", by_id[0x281][-1].data)
    p4, status = struct.unpack("<HH", by_id[0x381][-1].data)
    assert t_sup / 100 == pytest.approx(40.0, abs=0.01)
    assert t_rec / 100 == pytest.approx(state["t_recess"] - 273.15, abs=0.01)
    assert t_rec > t_groove > t_sup  # spinning warms the film
    assert flow / 100 == pytest.approx(state["flow"] * 60000, abs=0.01)  # L/min
    assert p_sup == round(1.2e6 / 0.6 / 1000)  # kPa
    recess = np.array([p1, p2, p3, p4])
    assert np.mean(recess) / p_sup == pytest.approx(0.6, abs=0.002)  # beta
    assert status == 0


async def _frames_of_fault(fault: str, during_s: float, after_s: float) -> tuple[list, list]:
    """The CAN frames on a fresh virtual bus while `fault` is on (its first 0.05 s left out) for
    `during_s` s, and in the `after_s` s after it is cleared."""
    channel = f"sim-test-{uuid.uuid4().hex[:8]}"
    bus = can.Bus(interface="virtual", channel=channel)
    try:
        async with SimRig(SimConfig(), can_channel=channel) as rig:
            rig.inject(fault)
            await collect(bus, 0.05)
            during = await collect(bus, during_s)
            rig.inject("clear")
            return during, await collect(bus, after_s)
    finally:
        bus.shutdown()


async def test_heartbeat_loss_and_recovery():
    lost, back = await _frames_of_fault("can_heartbeat_loss", 1.6, 0.6)
    assert not any(m.arbitration_id == 0x701 for m in lost)
    assert sum(m.arbitration_id == 0x181 for m in lost) >= 14  # process data go on
    assert any(m.arbitration_id == 0x701 for m in back)


async def test_a_silent_node_sends_nothing_until_cleared():
    silent, back = await _frames_of_fault("can_node_silent", 1.2, 0.6)
    assert silent == []  # neither heartbeat nor process data
    assert any(m.arbitration_id == 0x701 for m in back)
    assert sum(m.arbitration_id == 0x181 for m in back) >= 4


async def request(reader, writer, obj) -> dict:
    writer.write((json.dumps(obj) if not isinstance(obj, bytes) else obj.decode()).encode() + b"\n")
    await writer.drain()
    return json.loads(await reader.readline())


async def test_control_api():
    async with SimRig(SimConfig(), speedup=5.0, can_channel=None, control_port=0) as rig:
        host, port = rig.control_url.removeprefix("tcp://").split(":")
        assert host == "127.0.0.1"
        r, w = await asyncio.open_connection(host, int(port))
        try:
            st = await request(r, w, {"cmd": "state"})
            assert st["ok"] and st["spin"] == 0.0 and st["orbit"] == 0.0  # drives start stopped
            assert (await request(r, w, {"cmd": "set_manual", "orbit_radius": 9e-6, "recess_pressure": 1.5e6}))["ok"]
            assert rig.physics.manual.orbit_radius == 9e-6
            bad = await request(r, w, {"cmd": "set_manual", "orbit_radius": 1e-3})
            assert not bad["ok"] and "clearance" in bad["error"]
            tr = await request(r, w, {"cmd": "truth", "spin": 200.0, "orbit": -80.0})
            want = rig.truth(200.0, -80.0)
            for key in "KCD":
                np.testing.assert_allclose(tr[key], want[key])
            tp = await request(r, w, {"cmd": "true_phasors", "spin": 200.0, "orbit": -80.0})
            assert complex(*tp["phasors"]["y_a"]) == pytest.approx(rig.true_phasors(200.0, -80.0)["y_a"])
            tz = await request(r, w, {"cmd": "true_impedance", "spin": 200.0, "orbit": -80.0})
            np.testing.assert_allclose(np.array(tz["re"]) + 1j * np.array(tz["im"]), rig.true_impedance(200.0, -80.0))
            assert (await request(r, w, {"cmd": "local_control", "spin": 100.0, "orbit": 2 * math.pi * 5}))["ok"]
            await asyncio.sleep(0.05)
            st = await request(r, w, {"cmd": "state"})
            assert st["spin"] == pytest.approx(100.0) and st["orbit"] == pytest.approx(2 * math.pi * 5)
            assert (await request(r, w, {"cmd": "inject", "fault": "drop_frames", "count": 2}))["ok"]
            assert rig.board.drop == 2 or rig.board.frames_lost >= 2
            assert "unknown fault" in (await request(r, w, {"cmd": "inject", "fault": "x"}))["error"]
            assert "missing field" in (await request(r, w, {"cmd": "truth", "spin": 1.0}))["error"]
            assert "unknown cmd" in (await request(r, w, {"cmd": "fly"}))["error"]
            assert "bad request" in (await request(r, w, b"{not json"))["error"]
        finally:
            w.close()
