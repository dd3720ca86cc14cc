"""The test matrix as a plan: plain-data steps with estimated durations.

`make_plan(matrix, rig)` checks the matrix against the rig and expands it,
once, into a `Plan` (operating points and steps) that the run engine executes
as it is; it touches no hardware, so `orbitrig sweep --dry-run` lists it and
tests assert the sequence. Durations are PHYSICAL seconds (the time scale of
a simulated rig is the engine's business).

Operating points in the order that spends the least changeover time
(orbitrig.run.point_order; the written order is manual settings outermost,
spin innermost), unless the matrix says `order = "written"`. Per point::

    SetManual -> VerifyPressures -> SetSpin -> for each block:
        [SetOrbit] -> Settle -> Acquire -> [VerifyGeometry, first block] -> StoreBlock
    -> Identify -> CompletePoint
    ... StopDrives

Blocks run forward whirl from the highest |Omega| down, then backward from
the lowest up: the orbit drive never ramps through zero but once per point.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

from orbitrig.config import MPA, RPM, MatrixConfig, ModelSpec, PointOrder, RigConfig, check_matrix_against_rig
from orbitrig.errors import ConfigError
from orbitrig.run.plan_summary import PlanSummary as PlanSummary, summarize as summarize  # their old home
from orbitrig.run.point_order import fastest_order, manual_change_s
from reduction.rig_time import block_time
from reduction.whirl import Whirl

TWO_PI = 2.0 * math.pi
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

    @property
    def period(self) -> float:
        """Orbit period, physical s."""
        return TWO_PI / abs(self.orbit)


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

    def settings(self) -> dict[str, float | str]:
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
    """One step of the plan; `duration` is its estimated physical time (s)."""

    point: int | None
    duration: float  # estimated, physical s

    #: the step's kind in the dry run's summary ("store" covers blocks and points)
    word = "step"

    def describe(self) -> str:  # pragma: no cover - overridden
        return type(self).__name__


@dataclass(frozen=True)
class SetManual(Step):
    """The operator's hands set orbit radius, static eccentricity and pressures (SI)."""

    orbit_radius: float
    static_eccentricity: float
    recess_pressure: float
    pressure_ratio: float
    changed: bool  # differs from the previous point's settings

    word = "manual settings"

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
class VerifyPressures(Step):
    """Recess pressure and pressure ratio from CAN against the point's settings."""

    word = "verify"

    def describe(self) -> str:
        return "verify recess pressure and ratio from CAN"


@dataclass(frozen=True)
class SetSpin(Step):
    spin: float  # rad/s
    orbit: float  # rad/s signed: the point's first block, set together

    word = "spin changes"

    def describe(self) -> str:
        return f"set spin {self.spin / RPM:.0f} rpm (orbit {self.orbit / RPM:+.1f} rpm)"


@dataclass(frozen=True)
class SetOrbit(Step):
    block: Block

    word = "orbit changes"

    def describe(self) -> str:
        return f"set orbit {self.block.orbit / RPM:+.1f} rpm [{self.block.tag}]"


@dataclass(frozen=True)
class Settle(Step):
    block: Block
    hold: float  # s at setpoint

    word = "settle"

    def describe(self) -> str:
        return f"settle, {self.hold:g} s at setpoint [{self.block.tag}]"


@dataclass(frozen=True)
class AdaptiveTarget:
    """A block's adaptive averaging: until every channel's relative phasor uncertainty <= `target_pct`
    (percent), between min and max good revolutions; `expected`: its ratio's [orbit] `revolutions`."""

    target_pct: float
    min_revolutions: int
    max_revolutions: int
    expected: int | None = None


@dataclass(frozen=True)
class Acquire(Step):
    """Average exactly `revolutions` good revolutions (the block's count), or adaptively
    (`revolutions` is then the maximum, what the timeout and storage estimate assume; the
    duration assumes the expected count, else the maximum); after an interlock suspension
    the block is settled again (`hold` s at setpoint) and acquired anew."""

    block: Block
    revolutions: int
    hold: float  # s at setpoint when the block must be settled again
    adaptive: AdaptiveTarget | None = None  # None: exactly `revolutions`

    word = "acquire"

    def describe(self) -> str:
        a, what = self.adaptive, f"{self.revolutions} revolutions"
        if a is not None:
            about = "" if a.expected is None else f", about {a.expected} expected"
            what = f"{a.min_revolutions}..{a.max_revolutions} revolutions (until every channel <= {a.target_pct:g} %{about})"
        return f"acquire {what} at {self.block.orbit_hz:.3f} Hz [{self.block.tag}]"


@dataclass(frozen=True)
class VerifyGeometry(Step):
    """Orbit radius and static eccentricity of the block just acquired (probes); when
    they miss and the operator corrects them, `acquire` is repeated."""

    acquire: Acquire

    word = "verify"

    def describe(self) -> str:
        return "verify orbit radius and static eccentricity from the displacement probes"


@dataclass(frozen=True)
class StoreBlock(Step):
    block: Block

    word = "store"

    def describe(self) -> str:
        return f"store [{self.block.tag}]"


@dataclass(frozen=True)
class Identify(Step):
    models: tuple[ModelSpec, ...]

    word = "identify"

    def describe(self) -> str:
        names = ", ".join(f"{m.model}/{m.freq_dep}/{m.method}" for m in self.models)
        return f"identify ({names}) for piezo and strain, compare the two"


@dataclass(frozen=True)
class CompletePoint(Step):
    """Store the point's results and mark it complete (after the identification)."""

    word = "store"

    def describe(self) -> str:
        return "store point, mark complete"


@dataclass(frozen=True)
class StopDrives(Step):
    """The run's last step: both drives ramp to zero."""

    word = "stop drives"

    def describe(self) -> str:
        return "ramp both drives to zero"


#: every step kind of a plan (the engine has one handler for each)
STEP_KINDS: tuple[type[Step], ...] = (SetManual, VerifyPressures, SetSpin, SetOrbit, Settle, Acquire,
                                      VerifyGeometry, StoreBlock, Identify, CompletePoint, StopDrives)


# ---------------------------------------------------------------- expansion
def operating_points(matrix: MatrixConfig, rig: RigConfig) -> list[OperatingPoint]:
    """All operating points in the written order (manual settings outer, spin inner)."""
    op = matrix.operating
    ratios = matrix.orbit.ratio_list
    dirs = [Whirl(d).sign for d in matrix.orbit.directions]
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
    """Physical seconds to collect `revolutions` whole revolutions (reduction.rig_time.block_time)."""
    return block_time(orbit, revolutions)


@dataclass(frozen=True)
class Plan:
    """A matrix checked against the rig and expanded: the whole truth the engine runs."""

    matrix: MatrixConfig
    rig: RigConfig  # the rig it was checked against
    points: tuple[OperatingPoint, ...]
    steps: tuple[Step, ...]
    revolutions: int  # the most any block averages (a fixed count, or the adaptive maximum)
    order: tuple[int, ...] = ()  # per point run, its index in the written order (operating_points)

    @property
    def name(self) -> str:
        return self.matrix.name

    def point_steps(self, index: int) -> list[Step]:
        """The steps of operating point `index`, in order."""
        return [s for s in self.steps if s.point == index]

    @property
    def final_steps(self) -> list[Step]:
        """The steps after the last point (StopDrives)."""
        return [s for s in self.steps if s.point is None]


def make_plan(matrix: MatrixConfig, rig: RigConfig, order: Sequence[int] | None = None) -> Plan:
    """Check `matrix` against `rig` (ConfigError naming every problem) and expand it; the points
    run in `order` (indices of the written order; a resume passes the order its run started
    with), else in the matrix's `order` (orbitrig.run.point_order)."""
    check_matrix_against_rig(matrix, rig)
    written = operating_points(matrix, rig)
    if order is None:
        order = fastest_order(rig, written) if matrix.order == PointOrder.FASTEST else range(len(written))
    order = tuple(int(i) for i in order)
    if sorted(order) != list(range(len(written))):
        raise ConfigError(matrix.file, [f"the stored order of the operating points ({len(order)}) does not fit "
                                        f"the matrix's {len(written)} points"])
    points = [dataclasses.replace(written[w], index=i) for i, w in enumerate(order)]
    steps = _steps(matrix, rig, points)
    n_rev = max(s.revolutions for s in steps if isinstance(s, Acquire))
    return Plan(matrix, rig, tuple(points), tuple(steps), n_rev, order)


def block_acquire(matrix: MatrixConfig, rig: RigConfig, point: int, b: Block, hold: float) -> Acquire:
    """Block `b`'s Acquire: its ratio's fixed count ([orbit] revolutions, else the matrix's or rig.toml's),
    or with [averaging] its ratio's target; duration at the expected count (clamped), else the maximum."""
    a, expected = matrix.averaging, matrix.expected_revolutions(b.freq)
    if a is None:
        n = expected or matrix.revolutions or rig.averaging.revolutions
        return Acquire(point, acquisition_time(b.orbit, n), b, n, hold)
    target = matrix.orbit.target_pct_at(b.freq)
    pct = a.target_pct if target is None else target
    if pct is None:  # the matrix's validation requires one of the two
        raise ConfigError(matrix.file, [f"[averaging] target_pct or [orbit] target_pct: none for ratio {b.freq}"])
    rule = AdaptiveTarget(pct, a.min_revolutions, a.max_revolutions, expected)
    return Acquire(point, acquisition_time(b.orbit, expected or a.max_revolutions), b, a.max_revolutions, hold, rule)


def _steps(matrix: MatrixConfig, rig: RigConfig, points: list[OperatingPoint]) -> list[Step]:
    est = rig.estimates
    hold = rig.settle.hold_s if matrix.settle_hold_s is None else matrix.settle_hold_s
    rate = rig.ramp_rate
    models = tuple(matrix.models)
    steps: list[Step] = []
    spin_now = orbit_now = 0.0
    prev = None
    for p in points:
        changed = prev is None or p.manual != prev.manual
        steps.append(SetManual(p.index, manual_change_s(rig, prev, p) if changed else 0.0, *p.manual, changed))
        prev = p
        steps.append(VerifyPressures(p.index, est.verify_s))
        first = p.blocks[0]
        ramp = max(abs(p.spin - spin_now), abs(first.orbit - orbit_now)) / rate
        steps.append(SetSpin(p.index, ramp, p.spin, first.orbit))
        spin_now, orbit_now = p.spin, first.orbit
        for j, b in enumerate(p.blocks):
            if j:
                steps.append(SetOrbit(p.index, abs(b.orbit - orbit_now) / rate, b))
                orbit_now = b.orbit
            steps.append(Settle(p.index, hold, b, hold))
            acquire = block_acquire(matrix, rig, p.index, b, hold)
            steps.append(acquire)
            if j == 0:
                steps.append(VerifyGeometry(p.index, 0.0, acquire))
            steps.append(StoreBlock(p.index, est.store_s, b))
        steps.append(Identify(p.index, est.identify_s * len(models) * 2, models))
        steps.append(CompletePoint(p.index, est.store_s))
    steps.append(StopDrives(None, max(spin_now, abs(orbit_now)) / rate))
    return steps
