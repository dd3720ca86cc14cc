"""The plan's step kinds: plain data, one handler each in the engine (orbitrig.run.procedure).

Every step carries its operating point's index and its estimated PHYSICAL duration (s); `Block`
is one orbit frequency and direction. `orbitrig.run.plan` expands a matrix into these.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from orbitrig.config import MPA, ModelSpec
from orbitrig.run.sequential_rule import SequentialRule
from orbitrig.store.layout import point_name
from orbitrig.store.records import BlockChoice
from rigunits import in_hz, micrometres, rpm_text

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
        """The planned orbit frequency |Omega| / 2 pi, Hz (rigunits.in_hz: 5.0, not 4.999999999999999)."""
        return in_hz(abs(self.orbit))

    @property
    def period(self) -> float:
        """Orbit period, physical s."""
        return TWO_PI / abs(self.orbit)


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

    point: int  # always an operating point's
    orbit_radius: float
    static_eccentricity: float
    recess_pressure: float
    pressure_ratio: float
    changed: bool  # differs from the previous point's settings

    word = "manual settings"

    @property
    def step_id(self) -> str:
        return f"manual:{point_name(self.point)}"

    def describe(self) -> str:
        what = "set by hand" if self.changed else "unchanged, confirm"
        return (
            f"manual settings ({what}): orbit radius {micrometres(self.orbit_radius)}, "
            f"static eccentricity ratio {self.static_eccentricity:g} (e/C), recess pressure "
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
        return f"set spin {rpm_text(self.spin)} (orbit {rpm_text(self.orbit, signed=True)})"


@dataclass(frozen=True)
class SetOrbit(Step):
    block: Block

    word = "orbit changes"

    def describe(self) -> str:
        return f"set orbit {rpm_text(self.block.orbit, signed=True)} [{self.block.tag}]"


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
    """Store the block just acquired; a block a sequential point chose carries why (`choice`)."""

    block: Block
    choice: BlockChoice | None = None

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
    """Both drives ramp to a confirmed standstill: the run's last step (``point`` None), and
    before a point whose orbit radius is set by hand (``point`` that point)."""

    word = "stop drives"

    def describe(self) -> str:
        return "ramp both drives to zero"


@dataclass(frozen=True)
class ChooseBlocks(Step):
    """A sequential point's blocks after its initial list: chosen one by one at run time among
    the rule's candidates (SetOrbit, Settle, Acquire, StoreBlock each), until the target or the
    cap; `duration` is the most they may take (the cap less the initial blocks' estimate),
    `first_freq` the block index the first chosen block takes."""

    rule: SequentialRule
    hold: float  # s at setpoint before each chosen block
    first_freq: int
    revolutions: int  # the most its blocks may average in all (at the fastest candidate): storage estimates

    word = "sequential blocks (at most)"

    def describe(self) -> str:
        return self.rule.describe()


#: every step kind of a plan (the engine has one handler for each)
STEP_KINDS: tuple[type[Step], ...] = (
    SetManual,
    VerifyPressures,
    SetSpin,
    SetOrbit,
    Settle,
    Acquire,
    VerifyGeometry,
    StoreBlock,
    ChooseBlocks,
    Identify,
    CompletePoint,
    StopDrives,
)
