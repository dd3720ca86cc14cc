"""The simulator of `--sim` in a process of its own (orbitrig/cli/simulated_rig.py):
hands and truth over its control API, the scenario handed over whole, no orphan."""

from __future__ import annotations

import asyncio
import os
import signal
import sys
import time

import numpy as np
import pytest

from orbitrig.cli.simulated_rig import SimulatorError, simulated_rig
from sim.scenario_files import scenario
from sim.fits import constant_fit, power_fit
from sim.physics import RigPhysics

from support.cli_helpers import reaped, started


def alive(pid: int) -> bool:
    """Any thread of `pid` still running (a zombie leader whose other threads run is alive)."""
    try:
        tasks = os.listdir(f"/proc/{pid}/task")
    except FileNotFoundError:
        return False
    for tid in tasks:
        try:
            with open(f"/proc/{pid}/task/{tid}/stat") as f:
                if f.read().rsplit(")", 1)[1].split()[0] not in ("Z", "X"):
                    return True
        except FileNotFoundError:
            continue
    return False


def listening(port: int) -> bool:
    """Some socket listens on TCP `port` of this machine (read from /proc/net/tcp*)."""
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        with open(table) as f:
            for row in f.readlines()[1:]:
                local, state = row.split()[1], row.split()[3]
                if state == "0A" and int(local.rsplit(":", 1)[1], 16) == port:
                    return True
    return False


async def test_hands_and_truth_reach_the_simulator_process():
    cfg = scenario("clean")  # not the default: the scenario (and its seed) must cross over
    async with simulated_rig(40.0, cfg) as (sim, access):
        assert sim.proc.pid != os.getpid() and alive(sim.proc.pid)
        assert access.endpoints.can_interface == "serial" and access.endpoints.can_channel.startswith("socket://")
        await access.hands.set_manual(
            orbit_radius=5e-6, static_eccentricity=0.2, recess_pressure=0.6e6, pressure_ratio=0.45
        )
        manual = (await sim.link.acall("state"))["manual"]
        assert manual == {
            "orbit_radius": 5e-6,
            "static_eccentricity": 0.2,
            "recess_pressure": 0.6e6,
            "pressure_ratio": 0.45,
        }
        orbits = np.array([40.0, 80.0, 120.0])
        z = await asyncio.to_thread(access.truth.impedance, 200.0, orbits)
        fits = await asyncio.to_thread(access.truth.reference_fits, 200.0, orbits)
    here = RigPhysics(cfg)
    here.set_manual(orbit_radius=5e-6, static_eccentricity=0.2, recess_pressure=0.6e6, pressure_ratio=0.45)
    assert np.array_equal(z, here.impedances(200.0, orbits))  # JSON carries doubles exactly
    want = {"constant": constant_fit(orbits, z), "power": power_fit(orbits, z)}
    for kind, names in (("constant", "KCD"), ("power", ("K0", "Km", "C0", "Cn", "D0", "Dp"))):
        for name in names:
            assert np.allclose(fits[kind][name], want[kind][name], rtol=1e-12, atol=0), (kind, name)
    assert not alive(sim.proc.pid)  # ended with the context


async def test_a_simulator_that_cannot_start_is_one_error_with_its_reason():
    with pytest.raises(SimulatorError, match=r"did not start.*--speedup must be > 0"):
        async with simulated_rig(-1.0):
            pass


HOLDER = """
import asyncio, sys
from orbitrig.cli.simulated_rig import simulated_rig
async def main():
    async with simulated_rig(10.0) as (sim, access):
        print(sim.proc.pid, access.endpoints.modbus_url, flush=True)
        await asyncio.sleep(600)
asyncio.run(main())
"""


def test_no_orphan_when_the_application_is_killed():
    with reaped(started([sys.executable, "-c", HOLDER], stdin=None, stderr=None)) as app:
        child, modbus = app.stdout.readline().split()
        child = int(child)
        assert alive(child)
        os.kill(app.pid, signal.SIGKILL)  # no clean-up of its own: the kernel and the pipe tell
        app.wait(timeout=30)
        end = time.monotonic() + 10
        while alive(child) and time.monotonic() < end:
            time.sleep(0.05)
        assert not alive(child), "the simulator outlived the application"
        port = int(modbus.rsplit(":", 1)[1])
        assert not listening(port), "the simulator's Modbus port is still held"


async def test_a_simulator_that_ends_unasked_is_logged_with_its_exit_status(caplog):
    """The simulator process killed under a running service or sweep: its end is logged at once
    with its exit status (the run then fails on its lost links, and the log says why); an end
    that was asked is not logged."""
    async with simulated_rig(40.0) as (sim, _):
        with caplog.at_level("ERROR", logger="orbitrig.cli.simulator_process"):
            os.kill(sim.proc.pid, signal.SIGKILL)
            t0 = time.monotonic()
            while "ended unasked" not in caplog.text and time.monotonic() - t0 < 5.0:
                await asyncio.sleep(0.01)
            assert time.monotonic() - t0 < 2.0, caplog.text
        assert f"the simulator process (python -m sim, pid {sim.proc.pid}) ended unasked, exit status -9" in caplog.text
    caplog.clear()
    async with simulated_rig(40.0):
        pass
    await asyncio.sleep(0.1)
    assert "ended unasked" not in caplog.text
