"""The test matrix as a plan: plain-data steps with estimated durations.

`expand(matrix, rig)` turns a matrix into the steps one executor runs; it
touches no hardware, so `orbitrig sweep --dry-run` can list it and tests can
assert the sequence. Durations are PHYSICAL seconds (the simulator's speed-up
is the executor's business).

Per operating point (manual settings outermost, spin innermost, so the
operator changes the rig as rarely as possible)::

    SetManual -> Verify(pressures) -> SetSpin -> for each block:
        [SetOrbit] -> Settle -> Acquire -> [Verify(geometry), first block] -> Store
    -> Identify -> Store(point complete)
    ... StopDrives

Blocks run forward whirl from the highest |Omega| down, then backward from
the lowest up: the orbit drive never ramps through zero but once per point.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

from orbitrig.config import MPA, RPM, MatrixConfig, ModelSpec, RigConfig, check_matrix_against_rig

TWO_PI = 2.0 * math.pi
DIRECTIONS = {"forward": +1, "backward": -1}
DIR_TAG = {+1: "fwd", -1: "bwd"}


@dataclass(frozen=True)
class Block:
    """One orbit frequency and direction of an operating point."""

    freq: int  # index of |Omega| in the point's ascending frequency list
    direction: int  # +1 forward, -1 backward
    orbit: float  # rad/s, signed

    @property
    def tag(self) -> str:
        """Storage name, e.g. '03_bwd'."""
        return f"{self.freq:02d}_{DIR_TAG[self.direction]}"

    @property
    def orbit_hz(self) -> float:
        return abs(self.orbit) / TWO_PI


@dataclass(frozen=True)
class OperatingPoint:
    index: int
    spin: float  # rad/s
    recess_pressure: float  # Pa
    pressure_ratio: float  # -
    static_eccentricity: float  # -
    dynamic_eccentricity: float  # -
    orbit_radius: float  # m (commanded: eps_d * c)
    blocks: tuple[Block, ...]  # in execution order

    @property
    def spin_rpm(self) -> float:
        return self.spin / RPM

    @property
    def label(self) -> str:
        return (
            f"w{self.spin_rpm:.0f}rpm_pr{self.recess_pressure / MPA:.4g}MPa_b{self.pressure_ratio:g}"
            f"_es{self.static_eccentricity:g}_ed{self.dynamic_eccentricity:g}"
        )

    @property
    def manual(self) -> tuple[float, float, float, float]:
        return (self.orbit_radius, self.static_eccentricity, self.recess_pressure, self.pressure_ratio)

    def settings(self) -> dict:
        """Settings at the edges' units (for CSV, MQTT results, reports)."""
        return {
            "point": self.index,
            "label": self.label,
            "spin_rpm": round(self.spin_rpm, 6),
            "recess_pressure_mpa": round(self.recess_pressure / MPA, 9),
            "pressure_ratio": self.pressure_ratio,
            "static_eccentricity": self.static_eccentricity,
            "dynamic_eccentricity": self.dynamic_eccentricity,
        }


# ------------------------------------------------------------------ steps
@dataclass(frozen=True)
class Step:
    point: int | None
    duration: float  # estimated, physical s

    def describe(self) -> str:  # pragma: no cover - overridden
        return type(self).__name__


@dataclass(frozen=True)
class SetManual(Step):
    orbit_radius: float
    static_eccentricity: float
    recess_pressure: float
    pressure_ratio: float
    changed: bool  # differs from the previous point's settings

    @property
    def step_id(self) -> str:
        return f"manual:{self.point:04d}"

    def describe(self) -> str:
        what = "set by hand" if self.changed else "unchanged, confirm"
        return (
            f"manual settings ({what}): orbit radius {self.orbit_radius * 1e6:.2f} um, "
            f"static eccentricity {self.static_eccentricity:g}, recess pressure "
            f"{self.recess_pressure / MPA:.4g} MPa, pressure ratio {self.pressure_ratio:g}"
        )


@dataclass(frozen=True)
class Verify(Step):
    quantities: tuple[str, ...]  # "pressures" and/or "geometry"

    def describe(self) -> str:
        src = {"pressures": "recess pressure and ratio from CAN",
               "geometry": "orbit radius and static eccentricity from the displacement probes"}
        return "verify " + "; ".join(src[q] for q in self.quantities)


@dataclass(frozen=True)
class SetSpin(Step):
    spin: float  # rad/s
    orbit: float  # rad/s signed: the point's first block, set together

    def describe(self) -> str:
        return f"set spin {self.spin / RPM:.0f} rpm (orbit {self.orbit / RPM:+.1f} rpm)"


@dataclass(frozen=True)
class SetOrbit(Step):
    block: Block

    def describe(self) -> str:
        return f"set orbit {self.block.orbit / RPM:+.1f} rpm [{self.block.tag}]"


@dataclass(frozen=True)
class Settle(Step):
    block: Block
    hold: float  # s at setpoint

    def describe(self) -> str:
        return f"settle, {self.hold:g} s at setpoint [{self.block.tag}]"


@dataclass(frozen=True)
class Acquire(Step):
    block: Block
    revolutions: int

    def describe(self) -> str:
        return f"acquire {self.revolutions} revolutions at {self.block.orbit_hz:.3f} Hz [{self.block.tag}]"


@dataclass(frozen=True)
class Store(Step):
    block: Block | None  # None: the point is complete

    def describe(self) -> str:
        return f"store [{self.block.tag}]" if self.block else "store point, mark complete"


@dataclass(frozen=True)
class Identify(Step):
    models: tuple[ModelSpec, ...]

    def describe(self) -> str:
        names = ", ".join(f"{m.model}/{m.freq_dep}/{m.method}" for m in self.models)
        return f"identify ({names}) for piezo and strain, compare the two"


@dataclass(frozen=True)
class StopDrives(Step):
    def describe(self) -> str:
        return "ramp both drives to zero"


# ---------------------------------------------------------------- expansion
def operating_points(matrix: MatrixConfig, rig: RigConfig) -> list[OperatingPoint]:
    """All operating points in plan order (manual settings outer, spin inner)."""
    op = matrix.operating
    ratios = matrix.orbit.ratio_list
    dirs = [DIRECTIONS[d] for d in matrix.orbit.directions]
    c = rig.bearing.clearance
    points = []
    combos = itertools.product(
        op.recess_pressure_mpa, op.pressure_ratio, op.static_eccentricity, op.dynamic_eccentricity, op.spin_rpm
    )
    for i, (pr, beta, es, ed, rpm) in enumerate(combos):
        spin = rpm * RPM
        blocks = []
        if +1 in dirs:
            blocks += [Block(k, +1, +r * spin) for k, r in reversed(list(enumerate(ratios)))]
        if -1 in dirs:
            blocks += [Block(k, -1, -r * spin) for k, r in enumerate(ratios)]
        points.append(OperatingPoint(i, spin, pr * MPA, beta, es, ed, ed * c, tuple(blocks)))
    return points


def acquisition_time(orbit: float, revolutions: int) -> float:
    """Physical seconds to collect `revolutions` whole revolutions (one more to find the trigger)."""
    return (revolutions + 1) * TWO_PI / abs(orbit)


def expand(matrix: MatrixConfig, rig: RigConfig) -> list[Step]:
    """The whole run as steps, with estimated (physical) durations. No hardware."""
    check_matrix_against_rig(matrix, rig)
    est = rig.estimates
    n_rev = matrix.revolutions or rig.averaging.revolutions
    hold = rig.settle.hold_s if matrix.settle_hold_s is None else matrix.settle_hold_s
    rate = rig.ramp_rate
    models = tuple(matrix.models)
    steps: list[Step] = []
    spin_now = orbit_now = 0.0
    manual_prev = None
    for p in operating_points(matrix, rig):
        changed = p.manual != manual_prev
        manual_prev = p.manual
        steps.append(SetManual(p.index, est.manual_setting_s if changed else 0.0, *p.manual, changed))
        steps.append(Verify(p.index, est.verify_s, ("pressures",)))
        first = p.blocks[0]
        ramp = max(abs(p.spin - spin_now), abs(first.orbit - orbit_now)) / rate
        steps.append(SetSpin(p.index, ramp, p.spin, first.orbit))
        spin_now, orbit_now = p.spin, first.orbit
        for j, b in enumerate(p.blocks):
            if j:
                steps.append(SetOrbit(p.index, abs(b.orbit - orbit_now) / rate, b))
                orbit_now = b.orbit
            steps.append(Settle(p.index, hold, b, hold))
            steps.append(Acquire(p.index, acquisition_time(b.orbit, n_rev), b, n_rev))
            if j == 0:
                steps.append(Verify(p.index, 0.0, ("geometry",)))
            steps.append(Store(p.index, est.store_s, b))
        steps.append(Identify(p.index, est.identify_s * len(models) * 2, models))
        steps.append(Store(p.index, est.store_s, None))
    steps.append(StopDrives(None, max(spin_now, abs(orbit_now)) / rate))
    return steps


@dataclass
class PlanSummary:
    points: int
    blocks: int
    duration: float  # s, physical
    by_kind: dict[str, float] = field(default_factory=dict)


def summarize(steps: list[Step]) -> PlanSummary:
    by_kind: dict[str, float] = {}
    for s in steps:
        by_kind[type(s).__name__] = by_kind.get(type(s).__name__, 0.0) + s.duration
    points = {s.point for s in steps if s.point is not None}
    blocks = sum(isinstance(s, Acquire) for s in steps)
    return PlanSummary(len(points), blocks, sum(by_kind.values()), by_kind)


def format_duration(seconds: float) -> str:
    seconds = int(round(seconds))
    h, rem = divmod(seconds, 3600)
    m, s = divmod(rem, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"
