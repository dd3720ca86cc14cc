"""The test matrix as a plan: plain-data steps with estimated durations.

`make_plan(matrix, rig)` checks the matrix against the rig and expands it,
once, into a `Plan` (operating points and steps) that the run engine executes
as it is; it touches no hardware, so `orbitrig sweep --dry-run` lists it and
tests assert the sequence. Durations are PHYSICAL seconds (the time scale of
a simulated rig is the engine's business).

Operating points in the order that spends the least changeover time
(orbitrig.run.point_order; the written order is manual settings outermost,
spin innermost), unless the matrix says `order = "written"`. Per point::

    [StopDrives: the orbit radius changes] -> SetManual -> VerifyPressures -> SetSpin -> for each block:
        [SetOrbit] -> Settle -> Acquire -> [VerifyGeometry, first block] -> StoreBlock
    -> [ChooseBlocks: a sequential point's blocks chosen at run time] -> Identify -> CompletePoint
    ... StopDrives

Blocks run forward whirl from the highest |Omega| down, then backward from
the lowest up: the orbit drive never ramps through zero but once per point. Each entry
of the [orbit] list runs in the directions it names ([orbit] whirl), else in every one of
[orbit] directions; a block's `freq` is its entry's index in `orbit.ratio_list`.

The orbit radius is the outer spindle's adjustable offset, set by hand: before a point
whose radius differs from the previous point's both drives ramp to a confirmed standstill
(StopDrives). Static eccentricity and pressures are set with the drives turning (the paper
adjusts the static eccentricity while the apparatus runs).
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Sequence
from dataclasses import dataclass

from orbitrig.config import MPA, RPM, MatrixConfig, PointOrder, RigConfig, check_matrix_against_rig
from orbitrig.errors import ConfigError
from orbitrig.run.plan_summary import PlanSummary as PlanSummary, summarize as summarize  # their old home
from orbitrig.run.point_order import fastest_order, manual_change_s
from orbitrig.run.sequential_rule import SequentialRule, sequential_rule
from orbitrig.run.steps import (
    TWO_PI,
    Acquire,
    AdaptiveTarget,
    Block,
    ChooseBlocks,
    CompletePoint,
    Identify,
    SetManual,
    SetOrbit,
    SetSpin,
    Settle,
    Step,
    StopDrives,
    StoreBlock,
    VerifyGeometry,
    VerifyPressures,
)
from reduction.rig_time import block_time
from reduction.sequential import MAX_REVOLUTIONS
from reduction.whirl import Whirl
from rigunits import in_rpm


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
        """The spin speed as the matrix gave it, rpm (rigunits.in_rpm)."""
        return in_rpm(self.spin)

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
        """Settings at the edges' units (for CSV, MQTT results, reports). ``index`` is the point's
        0-based index (the run files' PPPP); ``point`` the same number, kept for older readers."""
        return {
            "index": self.index,
            "point": self.index,
            "label": self.label,
            "spin_rpm": self.spin_rpm,
            "recess_pressure_mpa": round(self.recess_pressure / MPA, 9),
            "pressure_ratio": self.pressure_ratio,
            "static_eccentricity": self.static_eccentricity,
            "dynamic_eccentricity": self.dynamic_eccentricity,
        }


# ---------------------------------------------------------------- expansion
def operating_points(matrix: MatrixConfig, rig: RigConfig) -> list[OperatingPoint]:
    """All operating points in the written order (manual settings outer, spin inner)."""
    op = matrix.operating
    ratios, whirl = matrix.orbit.ratio_list, matrix.orbit.whirl_list
    fwd = [(k, r) for k, r in enumerate(ratios) if Whirl.FORWARD in whirl[k].whirls]
    bwd = [(k, r) for k, r in enumerate(ratios) if Whirl.BACKWARD in whirl[k].whirls]
    c = rig.bearing.clearance
    points = []
    combos = itertools.product(
        op.recess_pressure_mpa, op.pressure_ratio, op.static_eccentricity, op.dynamic_eccentricity, op.spin_rpm
    )
    for i, (pr, beta, es, ed, rpm) in enumerate(combos):
        spin = rpm * RPM
        blocks = [Block(k, +1, +r * spin) for k, r in reversed(fwd)] + [Block(k, -1, -r * spin) for k, r in bwd]
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
    revolutions: int  # the most any block averages (a fixed count, the adaptive maximum, a chosen block's most)
    order: tuple[int, ...] = ()  # per point run, its index in the written order (operating_points)

    @property
    def name(self) -> str:
        return self.matrix.name

    def point_steps(self, index: int) -> list[Step]:
        """The steps of operating point `index`, in order."""
        return [s for s in self.steps if s.point == index]

    def blocks(self) -> dict[int, int | None]:
        """The orbit blocks each operating point measures, by its index (None: a sequential
        point's, chosen at run time); one pass over the steps."""
        count: dict[int, int | None] = {p.index: 0 for p in self.points}
        for s in self.steps:
            if s.point is None or (n := count[s.point]) is None:
                continue
            count[s.point] = None if isinstance(s, ChooseBlocks) else n + isinstance(s, Acquire)
        return count

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
        raise ConfigError(
            matrix.file,
            [
                f"the stored order of the operating points ({len(order)}) does not fit "
                f"the matrix's {len(written)} points"
            ],
        )
    points = [dataclasses.replace(written[w], index=i) for i, w in enumerate(order)]
    steps = _steps(matrix, rig, points)
    n_rev = max(
        s.revolutions if isinstance(s, Acquire) else MAX_REVOLUTIONS
        for s in steps
        if isinstance(s, (Acquire, ChooseBlocks))
    )
    return Plan(matrix, rig, tuple(points), tuple(steps), n_rev, order)


def block_acquire(matrix: MatrixConfig, rig: RigConfig, point: int, b: Block, hold: float) -> Acquire:
    """Block `b`'s Acquire: its ratio's fixed count ([orbit] revolutions, else the matrix's or rig.toml's),
    or with [averaging] its ratio's target; duration at the expected count (clamped), else the maximum."""
    a, expected = matrix.averaging, matrix.expected_revolutions(b.freq)
    if a is None:
        n = matrix.fixed_revolutions(b.freq, rig.averaging.revolutions)
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
        if prev is not None and p.orbit_radius != prev.orbit_radius:  # hands on the orbit spindle's offset
            steps.append(StopDrives(p.index, max(spin_now, abs(orbit_now)) / rate))
            spin_now = orbit_now = 0.0
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
        if (rule := sequential_rule(matrix, rig, p.spin)) is not None:
            steps.append(_choose_blocks(rule, hold, p, steps))
        steps.append(Identify(p.index, est.identify_s * len(models) * 2, models))
        steps.append(CompletePoint(p.index, est.store_s))
    steps.append(StopDrives(None, max(spin_now, abs(orbit_now)) / rate))
    return steps


def _choose_blocks(rule: SequentialRule, hold: float, p: OperatingPoint, steps: list[Step]) -> ChooseBlocks:
    """A sequential point's chosen blocks: at most the cap less the initial blocks' estimate."""
    initial = sum(s.duration for s in steps if s.point == p.index and isinstance(s, (Settle, Acquire, StoreBlock)))
    most = max(0.0, rule.cap_s - initial)
    revolutions = int(most * max(rule.candidates) * p.spin / TWO_PI) + 1
    return ChooseBlocks(p.index, most, rule, hold, 1 + max(b.freq for b in p.blocks), revolutions)
