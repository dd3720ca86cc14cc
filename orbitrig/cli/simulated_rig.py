"""The built-in simulator as the run engine sees it: the one place that builds it.

`simulated_rig(speedup)` starts the simulator in a process of its own
(`python -m sim`, sim/__main__.py) and yields it with its `RigAccess`: the
simulator's endpoints (Modbus TCP, the A/D board over TCP, the CAN bus over a
TCP hub: python-can interface "serial", sim/can_tcp.py), its speed-up as the
time scale, its manual settings as the operator's hands, its bearing's true
impedance Z(Omega) (and best fits of it) as the truth stored beside the
identified coefficients, and the scenario it runs (recorded in the run). The
engine gets only the access.

Why a process: the simulated drives trip on communication loss (fault 7510)
when a request is 1 s late, as real ones do. In the application's process the
simulator's physics and servers shared the interpreter lock with the service, so
a busy service made the *simulator* late. Hands and truth reach the process over
its control API (JSON lines on loopback TCP, docs/protocols/sim-control.md).

The child ends with the application: it runs in a session of its own (a Ctrl-C
on the terminal is the application's to handle, the drives ramp down under its
control), and it gets SIGTERM when its parent dies or closes the child's standard
input (sim/parent.py).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import socket
import subprocess
import threading
from collections.abc import AsyncIterator
from typing import TYPE_CHECKING, BinaryIO

import numpy as np

from orbitrig.cli.scenarios import default_scenario
from orbitrig.cli.sim_options import DEFAULT_SPEEDUP
from orbitrig.run.scenario import Scenario
from orbitrig.cli.simulator_process import SimulatorError, SimulatorStart, start_simulator

__all__ = ["SimulatorError", "simulated_access", "simulated_rig", "start_simulator"]

if TYPE_CHECKING:  # imported where used: the simulator starts before the engine's links are imported
    from orbitrig.run.rig_io import Endpoints, RigAccess

#: simulator time / wall time of `orbitrig sweep --sim` and `orbitrig serve --sim`


#: wall seconds one control request may take (the truth of a long point list on a loaded machine)
CALL_TIMEOUT = 60.0


class SimulatorLink:
    """The control API of a simulator process (JSON lines on loopback TCP), one request at a
    time from any thread. `call` blocks; `acall` waits in a worker thread."""

    def __init__(self, url: str):
        host, port = url.removeprefix("tcp://").rsplit(":", 1)
        self.address = (host, int(port))
        self._lock = threading.Lock()
        self._sock: socket.socket | None = None
        self._lines: BinaryIO | None = None

    def call(self, cmd: str, **fields) -> dict:
        """The reply of request `cmd` with `fields` (SI); SimulatorError when it is not ok."""
        with self._lock:
            try:
                if self._sock is None or self._lines is None:
                    self._sock = socket.create_connection(self.address, timeout=CALL_TIMEOUT)
                    self._lines = self._sock.makefile("rb")
                self._sock.sendall(json.dumps({"cmd": cmd, **fields}).encode() + b"\n")
                line = self._lines.readline()
            except OSError as err:
                self._drop()
                raise SimulatorError(f"simulator control {cmd}: {err}") from None
        if not line:
            raise SimulatorError(f"simulator control {cmd}: the simulator closed its control connection")
        reply = json.loads(line)
        if not reply.get("ok"):
            raise SimulatorError(f"simulator control {cmd}: {reply.get('error')}")
        return reply

    async def acall(self, cmd: str, **fields) -> dict:
        return await asyncio.to_thread(self.call, cmd, **fields)

    def close(self) -> None:
        with self._lock:
            self._drop()

    def _drop(self) -> None:
        if self._lines is not None:
            self._lines.close()
        if self._sock is not None:
            self._sock.close()
        self._sock = self._lines = None


class InProcessLink:
    """The same requests answered by a sim.rig.SimRig running in this process (tests that
    reach into the simulator): each request is handled at once, in the caller's thread."""

    def __init__(self, rig):
        self.rig = rig

    def call(self, cmd: str, **fields) -> dict:
        from sim.control import handle

        reply = handle(self.rig, {"cmd": cmd, **fields})
        if not reply["ok"]:
            raise SimulatorError(f"simulator control {cmd}: {reply['error']}")
        return reply

    async def acall(self, cmd: str, **fields) -> dict:
        return self.call(cmd, **fields)


class SimulatorHands:
    """The operator's hands on the simulator: the manual settings move it at once (SI)."""

    def __init__(self, link):
        self.link = link

    async def set_manual(
        self, *, orbit_radius: float, static_eccentricity: float, recess_pressure: float, pressure_ratio: float
    ) -> None:
        await self.link.acall(
            "set_manual",
            orbit_radius=orbit_radius,
            static_eccentricity=static_eccentricity,
            recess_pressure=recess_pressure,
            pressure_ratio=pressure_ratio,
        )

    async def apply_load(self, fx: float, fy: float) -> None:
        """A known static calibration load (N) on the simulator's journal, at once."""
        await self.link.acall("apply_load", fx=fx, fy=fy)

    async def apply_displacement(self, dx: float, dy: float) -> None:
        """A known static step (m) of the simulator's journal under the probes (0, 0: removed)."""
        await self.link.acall("apply_displacement", dx=dx, dy=dy)

    async def apply_reference(self, force: float, probe: float) -> None:
        """A calibrator on every channel's input of the simulator (N, m; 0, 0: removed)."""
        await self.link.acall("apply_reference", force=force, probe=probe)


class SimulatorTruth:
    """The simulator's bearing at its present manual settings (SI; spin, orbits rad/s).
    Blocking calls: the engine makes them in a worker thread."""

    def __init__(self, link):
        self.link = link

    def impedance(self, spin: float, orbits: np.ndarray) -> np.ndarray:
        """True Z (n, 2, 2) of the linearised bearing (f_bar = -Z d_bar)."""
        z = self.link.call("impedances", spin=float(spin), orbits=np.asarray(orbits, dtype=float).tolist())
        return np.asarray(z["re"], dtype=float) + 1j * np.asarray(z["im"], dtype=float)

    def reference_fits(self, spin: float, orbits: np.ndarray) -> dict:
        """Constant and Eq. 15 best fits of the true Z over `orbits` (sim.fits)."""
        return self.link.call("reference_fits", spin=float(spin), orbits=np.asarray(orbits, dtype=float).tolist())[
            "fits"
        ]


class SimulatorProcess:
    """A running `python -m sim` child: its announced `endpoints`, its control `link`."""

    def __init__(self, speedup: float, endpoints: dict, proc: subprocess.Popen):
        self.speedup, self.endpoints, self.proc = speedup, endpoints, proc
        self.link = SimulatorLink(endpoints["control"])

    @property
    def access_endpoints(self) -> Endpoints:
        from orbitrig.run.rig_io import Endpoints

        e = self.endpoints
        return Endpoints(e["modbus"], e["adc"], e["can"], "serial")

    @property
    def can_node_id(self) -> int | None:
        """Its CAN sensor node's node id, as its ready line says (None: no CAN node)."""
        return self.endpoints.get("can_node_id")

    def inject(self, fault: str, **kw) -> None:
        """A fault of the simulator (sim.injection.SimFault), through its control API."""
        self.link.call("inject", fault=fault, **kw)


def simulated_access(sim, scenario: Scenario | None = None) -> RigAccess:
    """How the engine reaches a simulator: a SimulatorProcess, or a sim.rig.SimRig running in
    this process (tests that reach into it); `scenario`: what it runs, recorded in the run."""
    from orbitrig.run.rig_io import Endpoints, RigAccess, TimeScale

    link: SimulatorLink | InProcessLink
    if isinstance(sim, SimulatorProcess):
        link, endpoints = sim.link, sim.access_endpoints
    else:
        link, endpoints = InProcessLink(sim), Endpoints(sim.modbus_url, sim.adc_url, sim.can_channel, "virtual")
    return RigAccess(
        endpoints=endpoints,
        time_scale=TimeScale(sim.speedup),
        hands=SimulatorHands(link),
        truth=SimulatorTruth(link),
        simulated=True,
        scenario=scenario,
    )


@contextlib.asynccontextmanager
async def simulated_rig(
    speedup: float = DEFAULT_SPEEDUP,
    config=None,
    scenario: Scenario | None = None,
    started: SimulatorStart | None = None,
    can_node_id: int | None = None,
) -> AsyncIterator[tuple[SimulatorProcess, RigAccess]]:
    """A simulator process of scenario `config` (a sim.config.SimConfig; default: the paper's
    rig) and its access; `scenario` names it in the run (the config's file and text; given neither,
    `default_scenario`); `can_node_id`: its CAN node's node id, the rig.toml's [transports]
    can_node_id that reads it (None: the scenario's, 1 by default).
    `started`: the process `start_simulator` started earlier with the same arguments."""
    if scenario is None and config is None:
        scenario = default_scenario()
    started = started or start_simulator(speedup, config, can_node_id)
    try:
        sim = SimulatorProcess(speedup, await started.ready(), started.proc)
    except BaseException:
        await started.end()
        raise
    watch = asyncio.create_task(started.watch(), name="simulator-watch")
    try:
        yield sim, simulated_access(sim, scenario)
    finally:
        sim.link.close()
        try:
            await started.end()
        finally:
            watch.cancel()  # done already if the process ended unasked; else it has ended now
