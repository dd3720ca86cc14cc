"""Are the manual settings what the point asks for? Pressures from CAN, geometry from the probes.

Each function returns the problems found (empty: verified), worded for the operator.
"""

from __future__ import annotations

import asyncio
import math
import time
from collections.abc import Awaitable, Callable
from typing import Protocol

from daq.aux import AuxState
from drives.waits import first_set
from orbitrig.config import MPA, RigConfig, Verify
from orbitrig.run.identification import probe_plane
from orbitrig.run.plan import OperatingPoint
from orbitrig.run.rig_io import TimeScale
from orbitrig.run.steps import SetManual
from orbitrig.store.records import BlockRecord
from reduction.whirl import Whirl, whirl_sense
from rigerrors import OrbitrigError
from rigunits import micrometres

#: physical s the pressures are given to reach their settings before the spindles start (at least 3 wall s)
PRESSURE_SETTLE_S = 20.0
#: wall s between two looks at the CAN readings without `arrival`: a frame is judged within this of its
#: arrival (the node sends every 0.1 s); with it each frame is judged as it arrives
LOOK_S = 0.01
#: a block whose orbit turns against its asked whirl by more than this (whirl_sense, 1: a circle) is not kept
WRONG_WHIRL_SENSE = 0.5
#: wall s at most between two looks with `arrival` (no frame meanwhile: the deadline, a suspension)
FRAME_WAIT_S = 0.1


class PressureSettings(Protocol):
    """The pressures asked for (an operating point, a calibration step's slow roll): Pa, -."""

    @property
    def recess_pressure(self) -> float: ...

    @property
    def pressure_ratio(self) -> float: ...


def pressure_problems(aux: AuxState, p: PressureSettings, v: Verify) -> list[str]:
    """Recess pressure (mean of the four recesses) and pressure ratio against the settings `p`."""
    if aux.node_lost:
        return ["no CAN sensor readings (node lost)"]
    if aux.stale("p_recess") or aux.stale("p_supply"):
        return ["CAN pressure readings are stale"]
    problems = []
    pr = sum(aux.p_recess) / len(aux.p_recess)
    if abs(pr - p.recess_pressure) > v.recess_pressure_tol_pct / 100 * p.recess_pressure:
        problems.append(
            f"recess pressure {pr / MPA:.4f} MPa, want {p.recess_pressure / MPA:.4f} MPa "
            f"+/- {v.recess_pressure_tol_pct:g} %"
        )
    beta = aux.beta if math.isfinite(aux.beta) else pr / aux.p_supply
    if abs(beta - p.pressure_ratio) > v.pressure_ratio_tol:
        problems.append(f"pressure ratio {beta:.3f}, want {p.pressure_ratio:g} +/- {v.pressure_ratio_tol:g}")
    return problems


async def pressures_settled(
    latest: Callable[[], AuxState],
    p: PressureSettings,
    v: Verify,
    scale: TimeScale,
    before_each: Callable[[], Awaitable[None]] | None = None,
    arrival: Callable[[], asyncio.Event] | None = None,
) -> list[str]:
    """The pressure problems (`pressure_problems` of the CAN node's `latest()` readings) left after
    waiting up to PRESSURE_SETTLE_S physical s (at least 3 wall s) for them to clear; empty: the
    pressures are met by readings on the bus after this check began (after the settings were made,
    not a frame sent before them and read since: AuxState.bus_ages). The check before the spindles start (a sweep's VerifyPressures, a
    calibration step's slow roll); `before_each()` is awaited before each reading. `arrival()`:
    the event the node's next frame sets (AuxSensors.arrival): the readings are looked at as each
    frame arrives, else every LOOK_S."""
    t0 = time.monotonic()
    deadline = t0 + max(3.0, scale.wall(PRESSURE_SETTLE_S))
    while True:
        if before_each is not None:
            await before_each()
        arrived = None if arrival is None else arrival()  # taken before the look: no frame missed
        aux = latest()
        problems = pressure_problems(aux, p, v)
        # p_recess and p_supply alike on the bus after the check began: a frame read since but sent
        # before (the settings not yet made) is not taken for the new pressures
        fresh = aux.bus_ages.get("beta", math.inf) < time.monotonic() - t0
        if (fresh and not problems) or time.monotonic() > deadline:  # by then an old reading is stale
            return problems
        if arrived is None:
            await asyncio.sleep(LOOK_S)
        else:
            await first_set(arrived, timeout=min(FRAME_WAIT_S, deadline - time.monotonic()))


def measured_radius(rec: BlockRecord, rig: RigConfig) -> float:
    """A block's orbit radius, m: the mean of the x and y amplitudes of the probe plane."""
    x, y = probe_plane(rec.phasors, rig.channel_index)
    return float((abs(x) + abs(y)) / 2)


def radius_missed(rec: BlockRecord, p: OperatingPoint, rig: RigConfig) -> bool:
    """Whether the block's orbit radius is outside the point's band (verify.orbit_radius_tol_pct)."""
    return abs(measured_radius(rec, rig) - p.orbit_radius) > rig.verify.orbit_radius_tol_pct / 100 * p.orbit_radius


def geometry_problems(rec: BlockRecord, p: OperatingPoint, rig: RigConfig) -> list[str]:
    """Orbit radius (m, mean of the x and y amplitudes) and static eccentricity (static
    displacement / clearance) of a block against the point's settings."""
    v, c = rig.verify, rig.bearing.clearance
    x0, y0 = probe_plane(rec.dc, rig.channel_index)
    radius = measured_radius(rec, rig)
    ecc = math.hypot(x0, y0) / c
    problems = []
    if radius_missed(rec, p, rig):
        problems.append(
            f"orbit radius {micrometres(radius)}, want {micrometres(p.orbit_radius)} +/- {v.orbit_radius_tol_pct:g} %"
        )
    if abs(ecc - p.static_eccentricity) > v.static_eccentricity_tol:
        problems.append(
            f"static eccentricity {ecc:.3f}, want {p.static_eccentricity:g} +/- {v.static_eccentricity_tol:g}"
        )
    return problems


class WrongWhirl(OrbitrigError):
    """A block's measured orbit turns the other way than the block asks (`whirl_missed`)."""


def whirl_missed(rec: BlockRecord, rig: RigConfig) -> str | None:
    """Why the block's measured orbit (the probes' mid-plane phasors) is not the whirl its block
    asks for, or None: revolutions from before the orbit drive reversed, an orbit motor turning
    against its drive, or the x and y probes swapped would each put the data under the wrong
    whirl, and the coefficients' cross terms with it."""
    x, y = probe_plane(rec.phasors, rig.channel_index)
    sense, asked = float(whirl_sense(x, y)), Whirl.of(rec.block.direction)
    if sense * asked.sign >= -WRONG_WHIRL_SENSE:
        return None
    return (
        f"the measured orbit turns {Whirl.of(sense)} (whirl sense {sense:+.2f}), the block asks {asked} whirl: "
        "revolutions from before the orbit drive reversed, the orbit motor turning against its drive "
        "(phases swapped?) or the x and y probes swapped"
    )


def setting_bands(p: OperatingPoint | SetManual, v: Verify) -> dict[str, list[float]]:
    """The band [low, high] (SI) each manual setting of ``p`` is accepted in by the checks above."""

    def around(value: float, half: float) -> list[float]:
        return [value - half, value + half]

    return {
        "orbit_radius": around(p.orbit_radius, v.orbit_radius_tol_pct / 100 * p.orbit_radius),
        "static_eccentricity": around(p.static_eccentricity, v.static_eccentricity_tol),
        "recess_pressure": around(p.recess_pressure, v.recess_pressure_tol_pct / 100 * p.recess_pressure),
        "pressure_ratio": around(p.pressure_ratio, v.pressure_ratio_tol),
    }
