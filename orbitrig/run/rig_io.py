"""How a run reaches the rig: endpoints, time scale, the operator's hands, and the open links.

The engine never knows whether the rig is real or simulated. It gets a
`RigAccess`: the transports to open (`Endpoints`), the `TimeScale` between
physical time and wall time (1 on the real rig), the `Hands` that make the
manual settings, and optionally a `TruthSource` (a simulated rig's exact
impedance, stored beside the identified coefficients) and the `Scenario` it
was built from (recorded in the run, so that a resume rebuilds the same rig). The real rig's access comes from the rig
configuration (`RigAccess.of_rig`); a simulated rig's is built where the
simulator is built (the command line).

`RigIO` is an async context manager around `drives.rig.RigDrives`,
`daq.adc.AdcReader` and `daq.aux.AuxSensors` opened at those endpoints: the
same protocol code runs on the rig and on the simulator.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field
from typing import Any, Callable, Protocol

import numpy as np
from daq.adc import AdcReader
from daq.averaging_rule import AveragingRule
from daq.averager import AveragedBlock
from daq.aux import AuxSensors
from daq.errors import DaqError
from daq.revolutions import Revolution
from drives.errors import DriveFaultError
from drives.rig import RigDrives
from drives.state import RigDriveState
from orbitrig.config import RigConfig
from orbitrig.run.drive_setup import rig_drives
from orbitrig.run.scenario import Scenario


@dataclass(frozen=True)
class Endpoints:
    """Where the rig's three links are: Modbus URL of the drives, A/D board URL, CAN bus."""

    modbus_url: str
    adc_url: str
    can_channel: str
    can_interface: str

    @classmethod
    def of_rig(cls, rig: RigConfig) -> "Endpoints":
        t = rig.transports
        return cls(t.modbus_url, t.adc_url, t.can_channel, t.can_interface)


@dataclass(frozen=True)
class TimeScale:
    """Physical time / wall time (1 on the real rig; a simulated rig may run faster)."""

    speedup: float = 1.0

    def wall(self, physical_s: float) -> float:
        """Wall seconds that `physical_s` physical seconds take."""
        return physical_s / self.speedup


class Hands(Protocol):
    """Whoever sets orbit radius (m), static eccentricity, recess pressure (Pa) and pressure ratio."""

    async def set_manual(
        self, *, orbit_radius: float, static_eccentricity: float, recess_pressure: float, pressure_ratio: float
    ) -> None: ...


class OperatorHands:
    """The real rig, hands that ask nothing: whoever holds them asks the operator and waits for the
    confirmation (a sweep's control prompt after `set_manual`). A calibration step asks in its own
    hands' `set_manual` (orbitrig.cli.calibrate_steps.OperatorLoads), before any spindle turns."""

    async def set_manual(
        self, *, orbit_radius: float, static_eccentricity: float, recess_pressure: float, pressure_ratio: float
    ) -> None:
        return None


class TruthSource(Protocol):
    """What a simulated rig knows exactly about its bearing (SI; spin, orbits rad/s)."""

    def impedance(self, spin: float, orbits: np.ndarray) -> np.ndarray:
        """True Z (n, 2, 2) complex, N/m, at each orbit speed: f_bar = -Z d_bar,
        Z = K + i|Omega| C - Omega^2 D for a bearing that has constant coefficients."""
        ...

    def reference_fits(self, spin: float, orbits: np.ndarray) -> dict[str, dict[str, Any]]:
        """Best fits of the true Z over `orbits`: {"constant": {"K", "C", "D"}, "power":
        {"K0", "Km", "C0", "Cn", "D0", "Dp", "exponents"}} (the paper's Eq. 15), 2x2 each."""
        ...


@dataclass(frozen=True)
class RigAccess:
    """Everything the engine needs to reach one rig."""

    endpoints: Endpoints
    time_scale: TimeScale = TimeScale()
    hands: Hands = field(default_factory=OperatorHands)
    truth: TruthSource | None = None
    simulated: bool = False  # recorded in the run file (a resume must use the same kind of rig)
    scenario: Scenario | None = None  # recorded in the run file (a resume rebuilds the same rig)

    @classmethod
    def of_rig(cls, rig: RigConfig) -> "RigAccess":
        return cls(Endpoints.of_rig(rig))


def can_node(rig: RigConfig, endpoints: Endpoints | None = None) -> AuxSensors:
    """The CAN sensor node's link of `rig` (its [transports]; the bus of `endpoints` if given), to
    be entered: the lubricant supply and the node itself as the interlocks read them."""
    t, e = rig.transports, endpoints or Endpoints.of_rig(rig)
    return AuxSensors(e.can_channel, interface=e.can_interface, bitrate=t.can_bitrate, node_id=t.can_node_id)


class RigIO:
    """The open links of one run: `drives`, `adc`, `aux` (entered in that reverse order)."""

    def __init__(
        self, rig: RigConfig, endpoints: Endpoints, *, on_revolution: Callable[[Revolution], None] | None = None
    ):
        self.rig = rig
        self.endpoints = endpoints
        self._on_revolution = on_revolution
        self._stack = contextlib.AsyncExitStack()
        self.drives: RigDrives | None = None
        self.adc: AdcReader | None = None
        self.aux: AuxSensors | None = None

    async def __aenter__(self) -> "RigIO":
        rig, t, e = self.rig, self.rig.transports, self.endpoints
        try:
            self.aux = await self._stack.enter_async_context(can_node(rig, e))
            self.adc = await self._stack.enter_async_context(
                AdcReader(
                    e.adc_url,
                    channels=len(rig.channels),
                    mode=t.adc_mode,
                    gains=rig.gains,
                    offsets=rig.offsets,
                    on_revolution=self._revolution,
                )
            )
            # entered last, so it is closed first: the drives stop before the links go
            self.drives = await self._stack.enter_async_context(rig_drives(e.modbus_url, rig.drives, watchdog=True))
        except BaseException:
            await self._stack.aclose()
            raise
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self._stack.aclose()

    @property
    def open_drives(self) -> RigDrives:
        """The drives' link, entered (a RuntimeError before: code that runs outside `async with`)."""
        if self.drives is None:
            raise RuntimeError("the drives are not open: use them inside `async with RigIO(...)`")
        return self.drives

    def drives_judged(self) -> RigDriveState:
        """The drives' latest poll for the interlocks, or what keeps the poll from judging them
        raised (`RigDrives.check`: a poll that failed on a bug, a failed verification after a
        link loss); a trip is not raised: the state shows it (orbitrig.run.interlocks)."""
        try:
            return self.open_drives.check()
        except DriveFaultError:
            return self.open_drives.state

    @property
    def open_aux(self) -> AuxSensors:
        """The CAN node's link, entered (a RuntimeError before, as `open_drives`)."""
        if self.aux is None:
            raise RuntimeError("the CAN node is not open: use it inside `async with RigIO(...)`")
        return self.aux

    def _revolution(self, rev: Revolution) -> None:
        if self._on_revolution is not None:
            self._on_revolution(rev)

    async def acquire(
        self, rule: AveragingRule | int, *, timeout: float, silence: float | None = None
    ) -> AveragedBlock:
        """Average good revolutions by `rule` (wall `timeout` s; a DaqTimeoutError once the board has
        sent nothing for `silence` wall s); the block carries their raw counts."""
        if self.adc is None:
            raise DaqError("the A/D board is not open: acquire inside `async with RigIO(...)`")
        return await self.adc.acquire(rule, timeout=timeout, silence=silence)
