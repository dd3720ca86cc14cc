"""The simulator's CAN node id from the command line: `orbitrig sim --can-node-id 5` (and `python -m
sim`'s, a scenario's [can] node_id) announces it and sends node 5's frames on its TCP bus; `sweep --sim`
and `calibrate --sim` start the simulator with the node id their rig.toml reads ([transports]
can_node_id 5): the run completes on node 5's heartbeat 0x705 (a simulator answering as node 1 would
leave the node lost and fail it after can_heartbeat_timeout_s). Bad ids are refused before anything
starts."""

from __future__ import annotations

import asyncio
import json
import shutil
from pathlib import Path

import pytest

from daq.aux import AuxSensors
from daq.errors import DaqError
from support.cli_helpers import orbitrig, orbitrig_started, reaped
from support.paths import ROOT
from support.rig_configs import patient_rig_config
from support.store_checks import small_matrix

pytestmark = pytest.mark.timeout(240)


def _rig_reading_node_5(folder: Path) -> Path:
    path = patient_rig_config(folder)
    text = path.read_text()
    assert "can_node_id = 1\n" in text
    path.write_text(text.replace("can_node_id = 1\n", "can_node_id = 5\n"))
    return path


async def _heard_as(channel: str, node_id: int) -> None:
    async with AuxSensors(channel, interface="serial", node_id=node_id) as aux:
        await aux.heard(5.0)


def test_orbitrig_sim_serves_the_node_id_given():
    ports = ("--modbus-port", "0", "--adc-port", "0", "--can-port", "0", "--control-port", "0")
    with reaped(orbitrig_started("sim", *ports, "--can-node-id", "5", stdin=None)) as proc:
        ep = json.loads(proc.stdout.readline())
        assert ep["can_node_id"] == 5, ep
        asyncio.run(_heard_as(ep["can"], 5))
        with pytest.raises(
            DaqError, match=r"no heartbeat from node 1 .*; heartbeat 0x705 heard \(node 5\), not node 1's 0x701"
        ):
            asyncio.run(_heard_as(ep["can"], 1))
        proc.terminate()
        assert proc.wait(timeout=10) == 0
        told = proc.stderr.read()
    assert "node id 5 (heartbeat 0x705)" in told and "can_node_id = 5" in told, told


@pytest.mark.parametrize("module", ["orbitrig", "sim"])
def test_a_can_node_id_outside_1_to_127_is_refused(module):
    import subprocess
    import sys

    if module == "orbitrig":
        p = orbitrig("sim", "--modbus-port", "0", "--adc-port", "0", "--can-node-id", "128")
        assert p.returncode == 2 and "--can-node-id" in p.stderr, p.stderr
    else:
        cmd = [sys.executable, "-m", "sim", "--can-node-id", "0"]
        p = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL)
        assert p.returncode == 2 and "--can-node-id 0: a CANopen node id is 1..127" in p.stderr, p.stderr


def test_a_scenario_sets_the_node_id_and_refuses_a_bad_one(tmp_path):
    from sim.scenario_files import sim_config_from_text

    assert sim_config_from_text("[can]\nnode_id = 5\n").can.node_id == 5
    assert sim_config_from_text("").can.node_id == 1  # the contract's node
    with pytest.raises(ValueError, match=r"s\.toml: .*can\.node_id must be a CANopen node id 1\.\.127, got 300"):
        sim_config_from_text("[can]\nnode_id = 300\n", "s.toml")
    with pytest.raises(ValueError, match=r"can\.node_id must be a CANopen node id 1\.\.127, got True"):
        sim_config_from_text("[can]\nnode_id = true\n", "s.toml")


def test_sweep_and_calibrate_sim_run_on_the_node_id_of_their_rig_toml(tmp_path):
    rig = _rig_reading_node_5(tmp_path / "lab")
    (tmp_path / "m.toml").write_text(small_matrix("node5", 10, spin_rpm=(1000.0,)))
    out = tmp_path / "run"
    p = orbitrig("sweep", "--sim", "--config", str(rig), "--matrix", str(tmp_path / "m.toml"), "--out", str(out))
    assert p.returncode == 0, p.stderr[-2000:]
    assert "CAN sensor node lost" not in (out / "run.log").read_text()
    shutil.copytree(ROOT / "config" / "calibration", tmp_path / "lab" / "calibration")
    args = ("calibrate", "runout", "--sim", "--config", str(rig), "--revolutions", "10", "--speedup", "20")
    p = orbitrig(*args)
    assert p.returncode == 0, p.stderr[-2000:]
    assert "CAN sensor node" not in p.stderr, p.stderr[-2000:]


def test_serve_sim_refuses_a_start_once_its_rig_toml_reads_another_node_than_the_simulators(tmp_path):
    """`serve --sim` starts the simulator as the node its rig.toml reads, and loads rig.toml again at
    each start: a can_node_id changed since is refused before anything moves (the simulator keeps its
    node; the run would find none and fail after can_heartbeat_timeout_s)."""
    from orbitrig.cli.serve import _reloaded
    from orbitrig.config import load_rig
    from orbitrig.service.rig_service import CommandRefused

    rig = _rig_reading_node_5(tmp_path / "lab")
    said = rf"{rig}: \[transports\] can_node_id 5: the simulator's CAN node is node 1, as `orbitrig serve --sim`"
    with pytest.raises(CommandRefused, match=said):
        _reloaded(rig, load_rig(ROOT / "config" / "rig.toml"), on_the_rig=False, sim_node=1)
    assert _reloaded(rig, load_rig(rig), on_the_rig=False, sim_node=5).transports.can_node_id == 5
    assert _reloaded(rig, load_rig(rig), on_the_rig=True).transports.can_node_id == 5  # on the rig: no simulator
