"""A test matrix (matrices/*.toml): operating points, orbit frequencies and
the identification models."""

from __future__ import annotations

from enum import StrEnum
from typing import Annotated, Literal

from pydantic import Field, PrivateAttr, ValidationInfo, field_validator, model_validator

from orbitrig.config.designs import resume_note, with_design
from orbitrig.config.fields import BY_VALUE, FREQ_DEP, MODELS, Mpa, Ratio, Rpm, Wait, FileConfig, ConfigModel
from orbitrig.config.sequential import SequentialDesign
from reduction.methods import Method
from reduction.whirl import Directions, Whirl


class PointOrder(StrEnum):
    """The order of a matrix's operating points (the matrix's top-level `order`)."""

    FASTEST = "fastest"
    WRITTEN = "written"


#: the fewest orbit frequencies a matrix may give (per direction)
MIN_RATIOS = 2


class Operating(ConfigModel):
    spin_rpm: Annotated[list[Rpm], Field(min_length=1)]
    recess_pressure_mpa: Annotated[list[Mpa], Field(min_length=1)]
    pressure_ratio: Annotated[list[Annotated[float, Field(gt=0, lt=1)]], Field(min_length=1)]
    static_eccentricity: Annotated[list[Annotated[float, Field(ge=0, lt=1)]], Field(min_length=1)]
    dynamic_eccentricity: Annotated[list[Annotated[float, Field(gt=0, lt=1)]], Field(min_length=1)]

    @field_validator("*")
    @classmethod
    def _no_repeats(cls, values: list[float], info: ValidationInfo) -> list[float]:
        """A value twice in a list would run its operating points twice (as [orbit] 'ratios')."""
        repeated = sorted({v for v in values if values.count(v) > 1})
        if repeated:
            twice = ", ".join(f"{v:g}" for v in repeated)
            raise ValueError(f"'{info.field_name}' has repeated values ({twice}): give each value once")
        return values

    @model_validator(mode="after")
    def _inside_the_clearance(self) -> Operating:
        """The orbit (radius eps_d c) about the static offset (eps_s c) stays inside the clearance c."""
        eps_s, eps_d = max(self.static_eccentricity), max(self.dynamic_eccentricity)
        if eps_s + eps_d >= 1:
            raise ValueError(
                f"static_eccentricity {eps_s:g} + dynamic_eccentricity {eps_d:g} = {eps_s + eps_d:g}: "
                "the journal would touch the bearing; their sum must stay below 1"
            )
        return self


#: revolutions averaged per block, fewest and most (a fixed count, or an adaptive rule's bounds)
MIN_REVOLUTIONS, MAX_REVOLUTIONS = 2, 10_000
Revolutions = Annotated[int, Field(ge=MIN_REVOLUTIONS, le=MAX_REVOLUTIONS)]
#: an adaptive averaging target: relative standard uncertainty of every channel, percent
TargetPct = Annotated[float, Field(gt=0, lt=100)]


class Orbit(ConfigModel):
    """Orbit frequencies as ratios Omega/omega: either `ratios` or start/stop/count, or a
    designed list by name (`design`, see orbitrig.config.designs: its ratios fill `ratios`).

    `revolutions` and `target_pct`, when given, hold one value per entry of `ratios` in the
    order written (both directions of a ratio alike): the block's fixed count, and its
    adaptive target (percent, with the matrix's [averaging]). `whirl`, when given, holds one
    direction per entry of `ratios` ("forward", "backward" or "both", each within
    `directions`): the entry runs only there, so a ratio may be written twice with directions
    that do not overlap (each entry its own count and target). Without it every ratio runs in
    every direction of `directions`. `ratio_list` sorts the entries (a ratio written twice is
    there twice, in the written order); `revolutions_at(k)` / `target_pct_at(k)` /
    `whirl_at(k)` give the values of `ratio_list[k]`."""

    design: str | None = None
    ratios: list[Ratio] | None = None
    ratio_start: Ratio | None = None
    ratio_stop: Ratio | None = None
    count: Annotated[int, Field(ge=MIN_RATIOS, le=100)] | None = None
    directions: Annotated[list[Annotated[Whirl, BY_VALUE]], Field(min_length=1)] = [Whirl.FORWARD, Whirl.BACKWARD]
    revolutions: list[Revolutions] | None = None
    target_pct: list[TargetPct] | None = None
    #: per entry of `ratios`: the directions it runs in (None: every one of `directions`)
    whirl: list[Annotated[Directions, BY_VALUE]] | None = None
    #: after the list above, blocks chosen one by one within the matrix's [sequential] bounds
    sequential: bool = False

    @field_validator("revolutions", "target_pct", "whirl")
    @classmethod
    def _one_per_ratio(cls, values, info: ValidationInfo):
        if values is None or "ratios" not in info.data:  # ratios invalid: reported on their own
            return values
        ratios = info.data["ratios"]
        if ratios is None:
            raise ValueError(
                "gives one value per entry of 'ratios': it needs 'ratios' (or a design), "
                "not 'ratio_start', 'ratio_stop', 'count'"
            )
        if len(values) != len(ratios):
            raise ValueError(
                f"has {len(values)} values and 'ratios' {len(ratios)}: give one per ratio, in the order of 'ratios'"
            )
        return values

    @model_validator(mode="after")
    def _one_spec(self):
        rng = (self.ratio_start, self.ratio_stop, self.count)
        problems = []  # every problem of the table, not only the first
        if self.ratios is not None and any(v is not None for v in rng):
            problems.append("give either 'ratios' or 'ratio_start', 'ratio_stop', 'count', not both")
        if self.ratios is None and any(v is None for v in rng):
            problems.append("give 'ratios' (a list) or all of 'ratio_start', 'ratio_stop', 'count'")
        if self.ratios is not None and len(self.ratios) < MIN_RATIOS:
            problems.append(
                f"'ratios' has {len(self.ratios)} value(s): give at least {MIN_RATIOS} orbit frequencies "
                "(one cannot separate the stiffness K from the added mass D or a frequency dependence)"
            )
        if self.ratios is not None and self.whirl is None and len(set(self.ratios)) != len(self.ratios):
            problems.append("'ratios' has repeated values (a ratio may be written twice only with a 'whirl' list)")
        problems += self._whirl_problems()
        if len(set(self.directions)) != len(self.directions):
            problems.append("'directions' has repeated values")
        if self.count is not None and self.count > 1 and None not in rng and self.ratio_start >= self.ratio_stop:
            problems.append("ratio_start must be smaller than ratio_stop")
        if problems:
            raise ValueError("; ".join(problems))
        return self

    def _whirl_problems(self) -> list[str]:
        """Each 'whirl' entry within 'directions', and a ratio written twice in directions that do not overlap."""
        if self.whirl is None or self.ratios is None:  # its length and 'ratios': _one_per_ratio
            return []
        allowed, problems = set(self.directions), []
        for i, w in enumerate(self.whirl):
            outside = [d.value for d in w.whirls if d not in allowed]
            if outside:
                problems.append(
                    f"'whirl[{i}]' is {w.value!r} (ratio {self.ratios[i]:g}): {' and '.join(outside)} is not in "
                    f"'directions' ({', '.join(self.directions)})"
                )
        for i, (r, w) in enumerate(zip(self.ratios, self.whirl)):
            for j in range(i):
                if self.ratios[j] == r and set(self.whirl[j].whirls) & set(w.whirls):
                    problems.append(
                        f"'ratios' has {r:g} twice (entries {j} and {i}) with 'whirl' {self.whirl[j].value!r} and "
                        f"{w.value!r}: a ratio written twice must run in directions that do not overlap "
                        "(one 'forward', one 'backward')"
                    )
        return problems

    @property
    def ratio_list(self) -> list[float]:
        """Orbit ratios |Omega|/omega, ascending."""
        if self.ratios is not None:
            return sorted(self.ratios)
        start, stop, count = self.ratio_start, self.ratio_stop, self.count
        if start is None or stop is None or count is None:  # refused by _one_spec
            raise ValueError("give 'ratios' (a list) or all of 'ratio_start', 'ratio_stop', 'count'")
        step = (stop - start) / (count - 1)
        return [round(start + k * step, 12) for k in range(count)]

    def _written(self, k: int) -> int:
        """Index in `ratios` (as written) of `ratio_list[k]` (ascending)."""
        ratios = self.ratios
        if ratios is None:  # refused by _one_per_ratio: revolutions / target_pct need 'ratios'
            raise ValueError("'revolutions' and 'target_pct' need 'ratios'")
        return sorted(range(len(ratios)), key=ratios.__getitem__)[k]

    def revolutions_at(self, k: int) -> int | None:
        """The fixed revolutions of `ratio_list[k]` (None: `revolutions` not given)."""
        return None if self.revolutions is None else self.revolutions[self._written(k)]

    def target_pct_at(self, k: int) -> float | None:
        """The adaptive target (percent) of `ratio_list[k]` (None: `target_pct` not given)."""
        return None if self.target_pct is None else self.target_pct[self._written(k)]

    def whirl_at(self, k: int) -> Directions:
        """The directions `ratio_list[k]` runs in: its `whirl` entry, else every one of `directions`."""
        return Directions.of(self.directions) if self.whirl is None else self.whirl[self._written(k)]

    @property
    def whirl_list(self) -> list[Directions]:
        """`whirl_at(k)` for every entry of `ratio_list`."""
        return [self.whirl_at(k) for k in range(len(self.ratio_list))]

    @property
    def per_direction(self) -> bool:
        """The list gives its entries' directions (`whirl`)."""
        return self.whirl is not None


class ModelSpec(ConfigModel):
    model: Literal[MODELS]  # type: ignore[valid-type]
    freq_dep: str = "none"
    method: Annotated[Method, BY_VALUE] = Method.OLS

    @field_validator("freq_dep")
    @classmethod
    def _freq_dep(cls, v: str) -> str:
        from reduction.errors import ReductionError
        from reduction.models import MAX_ORDER, parse_freq_dep

        allowed = f"allowed: none, power:M, power:m,n,p, power:auto, poly:R (integers 1..{MAX_ORDER})"
        if not FREQ_DEP.fullmatch(v):
            raise ValueError(allowed)
        try:
            parse_freq_dep(v)  # the identification's own limits, so a run never meets them first
        except ReductionError:
            raise ValueError(allowed) from None
        return v

    @property
    def key(self) -> str:
        """Storage name: model, freq-dep and method (two methods of one model must not collide)."""
        return f"{self.model}__{self.freq_dep.replace(':', '_').replace(',', '_')}__{self.method}"


class MatrixAveraging(ConfigModel):
    """Adaptive averaging of every block: stop once every channel's averaged phasor has a
    relative standard uncertainty <= the target (percent), between min_revolutions and
    max_revolutions good revolutions. The target is `target_pct`, or per ratio the [orbit]
    table's `target_pct` (one of the two). Without this table a block averages the matrix's
    `revolutions` (or [orbit] `revolutions` per ratio; default rig.toml's, the paper's 50)."""

    target_pct: TargetPct | None = None
    min_revolutions: Revolutions = 10
    max_revolutions: Revolutions = 200

    @model_validator(mode="after")
    def _order(self):
        if self.min_revolutions > self.max_revolutions:
            raise ValueError(
                f"min_revolutions ({self.min_revolutions}) must not exceed max_revolutions ({self.max_revolutions})"
            )
        return self


class DesignUsed(ConfigModel):
    """The design file of ``[orbit] design`` as the matrix read it: its name, path, SHA-256 and
    text (orbitrig.config.designs). A run stores it in the matrix's text (``run_text``)."""

    name: str
    file: str
    sha256: str
    text: str


class MatrixConfig(FileConfig):
    name: str
    description: str = ""
    operating: Operating
    orbit: Orbit
    models: Annotated[list[ModelSpec], Field(min_length=1)]
    revolutions: Revolutions | None = None
    averaging: MatrixAveraging | None = Field(None, validate_default=True)  # checked when absent too
    settle_hold_s: Wait | None = None
    #: the order of the operating points: "fastest" (the plan orders them to spend the least
    #: changeover time, orbitrig.run.point_order) or "written" (the product of [operating], in
    #: key order, the last varying fastest)
    order: Annotated[PointOrder, BY_VALUE] = PointOrder.FASTEST
    #: the bounds of a sequential point (orbitrig.config.sequential); with [orbit] sequential = true
    sequential: SequentialDesign | None = Field(None, validate_default=True)  # checked when absent too
    #: the design of [orbit] design as read (set by orbitrig.config.designs.apply_design: from the
    #: text's own [design_used] table, a run's stored copy, else from the design file)
    design_used: DesignUsed | None = None

    # cross-table checks as field validators, so each error names its key and line
    @field_validator("revolutions")
    @classmethod
    def _one_fixed_count(cls, v, info: ValidationInfo):
        orbit = info.data.get("orbit")
        if v is not None and orbit is not None and orbit.revolutions is not None:
            raise ValueError(
                "give the top-level 'revolutions' (one count for every block) or 'orbit.revolutions' "
                "(one per ratio), not both"
            )
        return v

    @field_validator("averaging")
    @classmethod
    def _one_target(cls, a, info: ValidationInfo):
        orbit = info.data.get("orbit")
        targets = None if orbit is None else orbit.target_pct
        problems = []
        if a is not None and info.data.get("revolutions") is not None:
            problems.append("give 'revolutions' (a fixed count) or an [averaging] table (adaptive), not both")
        if a is None and targets is not None:
            problems.append(
                "'orbit.target_pct' (adaptive targets per ratio) needs an [averaging] table "
                "(min_revolutions, max_revolutions)"
            )
        if a is not None and a.target_pct is not None and targets is not None:
            problems.append("give 'averaging.target_pct' (one target) or 'orbit.target_pct' (one per ratio), not both")
        if a is not None and a.target_pct is None and targets is None and orbit is not None:
            problems.append(
                "[averaging] needs a target: 'averaging.target_pct' (percent) or 'orbit.target_pct' (one per ratio)"
            )
        if problems:
            raise ValueError("; ".join(problems))
        return a

    @field_validator("sequential")
    @classmethod
    def _sequential_bounds(cls, v, info: ValidationInfo):
        orbit = info.data.get("orbit")
        if orbit is None:
            return v
        if orbit.sequential and v is None:
            raise ValueError(
                "'orbit.sequential = true' needs a [sequential] table: 'target_pct' or 'match_ratios', "
                "'cap_s' (rig seconds per point)"
            )
        if v is not None and not orbit.sequential:
            raise ValueError("a [sequential] table needs 'orbit.sequential = true'")
        return v

    @property
    def sequential_model(self) -> str | None:
        """The model a sequential point designs for (None: not sequential)."""
        s = self.sequential
        return None if s is None else s.model or self.models[0].model

    _file: str = PrivateAttr("<matrix>")

    @property
    def run_text(self) -> str:
        """The text a run stores: ``text`` with the design it used (designs.with_design)."""
        return with_design(self.text, self.design_used)

    @property
    def design_stored(self) -> bool:
        """The design came from the text's own [design_used] table (a run's stored matrix)."""
        return self.design_used is not None and self.run_text == self.text

    def as_stored(self, text: str) -> str:
        """``text`` (this stored matrix given again to a resume) as the run stored it: with this
        matrix's design when the run stored it, so the design file is not read again."""
        return with_design(text, self.design_used) if self.design_stored else text

    def resume_note(self) -> str | None:
        """The warning of a resume with this stored matrix (designs.resume_note; None: none)."""
        return resume_note(self)

    def fixed_revolutions(self, k: int, default: int) -> int:
        """The count a block at `orbit.ratio_list[k]` averages without [averaging]: its ratio's
        [orbit] revolutions, else the matrix's `revolutions`, else `default` (rig.toml's)."""
        return self.orbit.revolutions_at(k) or self.revolutions or default

    def expected_revolutions(self, k: int) -> int | None:
        """Revolutions a block at `orbit.ratio_list[k]` is expected to average: its `[orbit]
        revolutions` count, held within `[averaging]` min..max when averaging is adaptive
        (None: no per-ratio count)."""
        count, a = self.orbit.revolutions_at(k), self.averaging
        if count is None or a is None:
            return count
        return min(max(count, a.min_revolutions), a.max_revolutions)
