"""A matrix's [sequential] table: the bounds of a sequentially designed point.

With ``[orbit] sequential = true`` each operating point first runs the [orbit] list (the
initial blocks, which must identify the model: e.g. the model test's spread ratios at a few
revolutions each); then, block by block, the engine picks the next orbit ratio, direction
and revolutions among ``candidates`` (orbitrig.run.sequential_point, reduction.sequential)
until every coefficient of ``model`` reaches the target or the point's blocks have spent
``cap_s`` rig seconds. The target is either ``target_pct`` (every coefficient's predicted
relative standard error, percent of its matrix's size: reduction.frequency_list.
coefficient_scales) or ``match_ratios`` (every coefficient's predicted standard error at most
that of this list at ``match_revolutions`` per block, at the point's own noise and
coefficients: what `orbitrig design --match` asks).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Literal

from pydantic import Field, model_validator

from orbitrig.config.fields import MODELS, Ratio, Seconds, ConfigModel
from reduction.errors import ReductionError
from reduction.frequency_list import GRID_STEP, RUNOUT_KEEP_AWAY, allowed_ratios, near_one

if TYPE_CHECKING:
    from orbitrig.config.matrix import MatrixConfig
    from orbitrig.config.rig import Drives, RigConfig

#: revolutions of the reference list a sequential point matches
MatchRevolutions = Annotated[int, Field(ge=2, le=10_000)]


class SequentialDesign(ConfigModel):
    """The bounds of a sequential point (module doc); candidates None: the drives' band
    (rig.toml [drives] min_ratio..max_ratio, 0.05 steps, none within 0.1 of Omega/omega = 1)."""

    model: Literal[MODELS] | None = None  # type: ignore[valid-type]  # None: the first [[models]]
    target_pct: Annotated[float, Field(gt=0, le=1000)] | None = None
    match_ratios: list[Ratio] | None = None
    match_revolutions: MatchRevolutions = 50
    cap_s: Seconds = 600.0
    candidates: Annotated[list[Ratio], Field(min_length=1)] | None = None

    @model_validator(mode="after")
    def _one_target(self):
        if (self.target_pct is None) == (self.match_ratios is None):
            raise ValueError("give one target: 'target_pct' (percent) or 'match_ratios' (a reference list)")
        if self.candidates is not None and len(set(self.candidates)) != len(self.candidates):
            raise ValueError("'candidates' has repeated values")
        return self


def band_candidates(rig: RigConfig, spin_rpm: float) -> tuple[float, ...]:
    """The drives' band on the design grid at this spin: min_ratio .. max_ratio and the orbit
    drive's top speed, none within RUNOUT_KEEP_AWAY of 1."""
    d = rig.drives
    lo = d.min_ratio if d.min_ratio else GRID_STEP
    hi = min(d.max_ratio if d.max_ratio is not None else 2.0, d.max_orbit_rpm / spin_rpm)
    try:
        return tuple(float(r) for r in allowed_ratios(lo, hi))
    except ReductionError:
        return ()


#: a problem of a sequential matrix: the key path it is about (for its line), the message
KeyedProblem = tuple[tuple[str, ...], str]


def below_band(drives: Drives, ratio: float) -> str | None:
    """An orbit `ratio` below the rig's drives.min_ratio, said (None: not below)."""
    if drives.min_ratio is None or ratio >= drives.min_ratio:
        return None
    return f"ratio {ratio:g} is below the rig's drives.min_ratio = {drives.min_ratio:g}"


def above_band(drives: Drives, ratio: float) -> str | None:
    """An orbit `ratio` above the rig's drives.max_ratio, said (None: not above)."""
    if drives.max_ratio is None or ratio <= drives.max_ratio:
        return None
    return f"ratio {ratio:g} is above the rig's drives.max_ratio = {drives.max_ratio:g}"


def orbit_too_fast(drives: Drives, ratio: float, spin_rpm: float) -> str | None:
    """An orbit of `ratio` at `spin_rpm` faster than the rig's drives.max_orbit_rpm, said (None: not)."""
    if (top := ratio * spin_rpm) <= drives.max_orbit_rpm:
        return None
    return f"ratio {ratio:g} at {spin_rpm:g} rpm gives {top:g} rpm orbit, above the rig's drives.max_orbit_rpm = {drives.max_orbit_rpm:g}"


def ratio_problems(drives: Drives, ratio: float, spin_rpm: float) -> list[str]:
    """What is wrong with an orbit of `ratio` at `spin_rpm` on the rig's [drives] (a sequential
    point's candidates and reference list; a matrix's [orbit] list: orbitrig.config.plan_checks)."""
    said = (below_band(drives, ratio), above_band(drives, ratio), orbit_too_fast(drives, ratio, spin_rpm))
    return [words for words in said if words is not None]


def candidate_problems(matrix: MatrixConfig, rig: RigConfig) -> list[KeyedProblem]:
    """What is wrong with a sequential matrix's explicit candidates and reference list on this
    rig: (key path, message naming the key), the key path giving the line of the key itself
    (orbitrig.config.plan_checks); [] when it is not sequential."""
    s = matrix.sequential
    if s is None:
        return []
    d = rig.drives
    problems: list[KeyedProblem] = []
    for key, ratios in (("candidates", s.candidates), ("match_ratios", s.match_ratios)):
        loc = ("sequential", key)
        for r in ratios or ():
            said = ratio_problems(d, r, max(matrix.operating.spin_rpm))
            problems += [(loc, f"key 'sequential.{key}': {words}") for words in said]
            if key == "candidates" and near_one(r, RUNOUT_KEEP_AWAY):
                problems.append(
                    (
                        loc,
                        f"key 'sequential.candidates': ratio {r:g} is within {RUNOUT_KEEP_AWAY:g} of "
                        "Omega/omega = 1 (the orbit cannot be told from the spindle's runout)",
                    )
                )
    for rpm in matrix.operating.spin_rpm:
        if s.candidates is None and not band_candidates(rig, rpm):
            problems.append(
                (
                    ("sequential",),
                    f"key 'sequential': no candidate ratio in the drives' band at {rpm:g} rpm; "
                    "give 'sequential.candidates'",
                )
            )
    return problems
