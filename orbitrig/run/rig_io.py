"""Opening the rig's hardware for one run: drives, A/D board, CAN sensor node.

`RigIO` is an async context manager around `drives.rig.RigDrives`,
`daq.adc.AdcReader` and `daq.aux.AuxSensors`, opened at the transports of
`config/rig.toml` or, in --sim mode, at the endpoints of an in-process
`sim.rig.SimRig` (Modbus TCP, A/D over a TCP socket, a python-can virtual
bus): the same protocol code runs in both cases. The only sim-specific
calls are `set_manual` (the operator's hands) and `truth`.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
from typing import Callable

import numpy as np

from orbitrig.config import RigConfig


@dataclass
class Acquisition:
    """An averaged block (it carries the raw counts of exactly the revolutions in it)."""

    block: object  # daq.averager.AveragedBlock
    raw_counts: np.ndarray  # int16 (N, C, S)
    slots: np.ndarray  # (C, S)


def sim_speedup(sim) -> float:
    """Time speed-up of a SimRig (1 for the real rig, `sim` None)."""
    if sim is None:
        return 1.0
    speedup = getattr(sim, "speedup", None)
    if speedup is None:
        speedup = sim.clock.speedup
    return float(speedup)


class RigIO:
    def __init__(self, rig: RigConfig, *, sim=None, on_revolution: Callable[[object], None] | None = None):
        self.rig = rig
        self.sim = sim
        self.speedup = sim_speedup(sim)
        self._on_revolution = on_revolution
        self._stack = contextlib.AsyncExitStack()
        self.drives = None
        self.adc = None
        self.aux = None

    async def __aenter__(self) -> "RigIO":
        from daq.adc import AdcReader
        from daq.aux import AuxSensors
        from drives.rig import DriveLimits, RigDrives

        rig, t = self.rig, self.rig.transports
        d = rig.drives
        if self.sim is not None:
            modbus_url, adc_url = self.sim.modbus_url, self.sim.adc_url
            can_channel, can_interface = self.sim.can_channel, "virtual"
        else:
            modbus_url, adc_url = t.modbus_url, t.adc_url
            can_channel, can_interface = t.can_channel, t.can_interface
        limits = DriveLimits(max_spin=rig.max_spin, max_orbit=rig.max_orbit, min_ratio=d.min_ratio,
                             max_ratio=d.max_ratio)  # fmt: skip
        try:
            self.aux = await self._stack.enter_async_context(
                AuxSensors(can_channel, interface=can_interface, bitrate=t.can_bitrate, node_id=t.can_node_id)
            )
            self.adc = await self._stack.enter_async_context(
                AdcReader(adc_url, channels=len(rig.channels), mode=t.adc_mode, gains=rig.gains,
                          offsets=rig.offsets, on_revolution=self._revolution)  # fmt: skip
            )
            # entered last, so it is closed first: the drives stop before the links go
            self.drives = await self._stack.enter_async_context(
                RigDrives(modbus_url, limits, poll_interval=d.poll_interval_s, spin_id=d.spin_id,
                          orbit_id=d.orbit_id, timeout=d.timeout_s,
                          link_loss_polls=d.link_loss_polls)  # fmt: skip
            )
        except BaseException:
            await self._stack.aclose()
            raise
        return self

    async def __aexit__(self, *exc) -> None:
        await self._stack.aclose()

    # ---------------------------------------------------------------- A/D
    def _revolution(self, rev) -> None:
        if self._on_revolution is not None:
            self._on_revolution(rev)

    async def acquire(self, n_revolutions, *, timeout: float) -> Acquisition:
        """Average good revolutions (`n_revolutions`: a count, or a daq.averager.AveragingRule);
        the block carries their raw counts."""
        block = await self.adc.acquire(n_revolutions, timeout=timeout)
        return Acquisition(block, block.raw_counts, block.slots)

    # ---------------------------------------------------------- sim only
    def set_manual(self, *, orbit_radius: float, static_eccentricity: float, recess_pressure: float,
                   pressure_ratio: float) -> None:  # fmt: skip
        self.sim.set_manual(orbit_radius=orbit_radius, static_eccentricity=static_eccentricity,
                            recess_pressure=recess_pressure, pressure_ratio=pressure_ratio)  # fmt: skip

    def truth(self, spin: float, orbit: float) -> dict:
        return self.sim.truth(spin, orbit)
