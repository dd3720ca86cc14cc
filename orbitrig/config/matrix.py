"""A test matrix (matrices/*.toml): operating points, orbit frequencies and
the identification models."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, PrivateAttr, field_validator, model_validator

from orbitrig.config.fields import FREQ_DEP, MODELS, Mpa, Ratio, Rpm, Wait, _Model


class Operating(_Model):
    spin_rpm: Annotated[list[Rpm], Field(min_length=1)]
    recess_pressure_mpa: Annotated[list[Mpa], Field(min_length=1)]
    pressure_ratio: Annotated[list[Annotated[float, Field(gt=0, lt=1)]], Field(min_length=1)]
    static_eccentricity: Annotated[list[Annotated[float, Field(ge=0, lt=1)]], Field(min_length=1)]
    dynamic_eccentricity: Annotated[list[Annotated[float, Field(gt=0, lt=1)]], Field(min_length=1)]


class Orbit(_Model):
    """Orbit frequencies as ratios Omega/omega: either `ratios` or start/stop/count, or a
    designed list by name (`design`, see orbitrig.config.designs: its ratios fill `ratios`)."""

    design: str | None = None
    ratios: list[Ratio] | None = None
    ratio_start: Ratio | None = None
    ratio_stop: Ratio | None = None
    count: Annotated[int, Field(ge=1, le=100)] | None = None
    directions: Annotated[list[Literal["forward", "backward"]], Field(min_length=1)] = ["forward", "backward"]

    @model_validator(mode="after")
    def _one_spec(self):
        rng = (self.ratio_start, self.ratio_stop, self.count)
        problems = []  # every problem of the table, not only the first
        if self.ratios is not None and any(v is not None for v in rng):
            problems.append("give either 'ratios' or 'ratio_start', 'ratio_stop', 'count', not both")
        if self.ratios is None and any(v is None for v in rng):
            problems.append("give 'ratios' (a list) or all of 'ratio_start', 'ratio_stop', 'count'")
        if self.ratios is not None and len(set(self.ratios)) != len(self.ratios):
            problems.append("'ratios' has repeated values")
        if len(set(self.directions)) != len(self.directions):
            problems.append("'directions' has repeated values")
        if (self.count is not None and self.count > 1 and None not in rng
                and self.ratio_start >= self.ratio_stop):
            problems.append("ratio_start must be smaller than ratio_stop")
        if problems:
            raise ValueError("; ".join(problems))
        return self

    @property
    def ratio_list(self) -> list[float]:
        """Orbit ratios |Omega|/omega, ascending."""
        if self.ratios is not None:
            return sorted(self.ratios)
        if self.count == 1:
            return [self.ratio_start]
        step = (self.ratio_stop - self.ratio_start) / (self.count - 1)
        return [round(self.ratio_start + k * step, 12) for k in range(self.count)]


class ModelSpec(_Model):
    model: Literal[MODELS]  # type: ignore[valid-type]
    freq_dep: str = "none"
    method: Literal["ols", "wls", "tls", "iv"] = "ols"

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


class MatrixAveraging(_Model):
    """Adaptive averaging of every block: stop once every channel's averaged phasor has a
    relative standard uncertainty <= target_pct (percent), between min_revolutions and
    max_revolutions good revolutions. Without this table a block averages the matrix's
    `revolutions` (default rig.toml's, the paper's 50)."""

    target_pct: Annotated[float, Field(gt=0, lt=100)]
    min_revolutions: Annotated[int, Field(ge=2, le=10_000)] = 10
    max_revolutions: Annotated[int, Field(ge=2, le=10_000)] = 200

    @model_validator(mode="after")
    def _order(self):
        if self.min_revolutions > self.max_revolutions:
            raise ValueError(f"min_revolutions ({self.min_revolutions}) must not exceed "
                             f"max_revolutions ({self.max_revolutions})")
        return self


class MatrixConfig(_Model):
    name: str
    description: str = ""
    operating: Operating
    orbit: Orbit
    models: Annotated[list[ModelSpec], Field(min_length=1)]
    revolutions: Annotated[int, Field(ge=2, le=10_000)] | None = None
    averaging: MatrixAveraging | None = None
    settle_hold_s: Wait | None = None

    @model_validator(mode="after")
    def _one_count(self):
        if self.averaging is not None and self.revolutions is not None:
            raise ValueError("give 'revolutions' (a fixed count) or an [averaging] table (adaptive), not both")
        return self

    _file: str = PrivateAttr("<matrix>")
    _text: str = PrivateAttr("")

    @property
    def file(self) -> str:
        return self._file

    @property
    def text(self) -> str:
        return self._text
