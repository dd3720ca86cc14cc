"""The built-in simulator as the run engine sees it: the one place that builds it.

`simulated_rig(speedup)` starts an in-process `sim.rig.SimRig` (Modbus TCP,
A/D over a TCP socket, a python-can virtual bus) and yields it with its
`RigAccess`: the simulator's endpoints, its speed-up as the time scale, its
manual settings as the operator's hands, its bearing's true impedance Z(Omega)
(and best fits of it) as the truth stored beside the identified coefficients, and
the scenario it runs (recorded in the run). The engine gets only the access.
"""

from __future__ import annotations

import asyncio
import contextlib
import threading
from collections.abc import AsyncIterator

import numpy as np

from orbitrig.run.rig_io import Endpoints, RigAccess, Scenario, TimeScale
from sim.config import SimConfig
from sim.rig import SimRig

#: simulator time / wall time of `orbitrig sweep --sim` and `orbitrig serve --sim`
DEFAULT_SPEEDUP = 40.0


class SimulatorHands:
    """The operator's hands on the simulator: the manual settings move it at once."""

    def __init__(self, sim: SimRig):
        self.sim = sim

    def set_manual(self, *, orbit_radius: float, static_eccentricity: float, recess_pressure: float,
                   pressure_ratio: float) -> None:  # fmt: skip
        self.sim.set_manual(orbit_radius=orbit_radius, static_eccentricity=static_eccentricity,
                            recess_pressure=recess_pressure, pressure_ratio=pressure_ratio)  # fmt: skip

    async def apply_load(self, fx: float, fy: float) -> None:
        """A known static calibration load (N) on the simulator's journal, at once."""
        self.sim.physics.apply_load(fx, fy)

    async def apply_displacement(self, dx: float, dy: float) -> None:
        """A known static step (m) of the simulator's journal under the probes (0, 0: removed)."""
        self.sim.physics.apply_displacement(dx, dy)

    async def apply_reference(self, force: float, probe: float) -> None:
        """A calibrator on every channel's input of the simulator (N, m; 0, 0: removed)."""
        self.sim.physics.apply_reference(force, probe)


class SimulatorTruth:
    """The simulator's bearing at its present manual settings (SI; spin, orbits rad/s)."""

    def __init__(self, sim: SimRig):
        self.sim = sim

    def impedance(self, spin: float, orbits: np.ndarray) -> np.ndarray:
        """True Z (n, 2, 2) of the linearised bearing (f_bar = -Z d_bar)."""
        return self.sim.true_impedances(spin, orbits)

    def reference_fits(self, spin: float, orbits: np.ndarray) -> dict:
        """Constant and Eq. 15 best fits of the true Z over `orbits` (sim.fits)."""
        return self.sim.reference_fits(spin, orbits)


def simulated_access(sim: SimRig, scenario: Scenario | None = None) -> RigAccess:
    """How the engine reaches a running SimRig (`scenario`: what it runs, recorded in the run)."""
    return RigAccess(
        endpoints=Endpoints(sim.modbus_url, sim.adc_url, sim.can_channel, "virtual"),
        time_scale=TimeScale(sim.speedup), hands=SimulatorHands(sim), truth=SimulatorTruth(sim),
        simulated=True, scenario=scenario,
    )  # fmt: skip


@contextlib.asynccontextmanager
async def simulated_rig(speedup: float = DEFAULT_SPEEDUP, config: SimConfig | None = None,
                        scenario: Scenario | None = None) -> AsyncIterator[tuple[SimRig, RigAccess]]:  # fmt: skip
    """A running SimRig of scenario `config` (default: the paper's rig; no pty: the A/D
    board over TCP) and its access; `scenario` names it in the run (the config's file and text).

    The simulator runs on an event loop of its own, in a thread: its physics and its
    servers never hold up the loop that polls its drives (as on the rig, where they are
    other machines). Manual settings and the truth are plain calls into it."""
    host = _SimulatorThread(config, speedup)
    sim = await host.start()
    try:
        yield sim, simulated_access(sim, scenario)
    finally:
        await host.stop()


class _SimulatorThread:
    """A SimRig served by its own event loop in a daemon thread."""

    def __init__(self, config: SimConfig | None, speedup: float):
        self.config, self.speedup = config, speedup
        self.ready = threading.Event()
        self.sim: SimRig | None = None
        self.error: BaseException | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None
        self._thread = threading.Thread(target=lambda: asyncio.run(self._serve()), name="simulator", daemon=True)

    async def _serve(self) -> None:
        self._loop, self._stop = asyncio.get_running_loop(), asyncio.Event()
        try:
            async with SimRig(self.config, speedup=self.speedup, adc_pty=False) as sim:
                self.sim = sim
                self.ready.set()
                await self._stop.wait()
        except BaseException as err:  # noqa: BLE001 - raised again in the caller's thread
            self.error = err
        finally:
            self.ready.set()

    async def start(self) -> SimRig:
        self._thread.start()
        await asyncio.to_thread(self.ready.wait)
        if self.sim is None:
            raise self.error or RuntimeError("the simulator did not start")
        return self.sim

    async def stop(self) -> None:
        if self._loop is not None and not self._loop.is_closed():
            with contextlib.suppress(RuntimeError):  # its loop already ended
                self._loop.call_soon_threadsafe(self._stop.set)
        await asyncio.to_thread(self._thread.join, 30.0)
