"""A plan's totals for the dry run and the bench: points, blocks, estimated physical time per
kind of step (`Step.word`); rigunits.format_duration prints them."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from orbitrig.run.steps import Step


@dataclass
class PlanSummary:
    points: int
    blocks: int
    duration: float  # s, physical
    by_kind: dict[str, float] = field(default_factory=dict)


def summarize(steps: Sequence[Step]) -> PlanSummary:
    """Points, blocks and estimated time, with the time per kind of step (`Step.word`)."""
    by_kind: dict[str, float] = {}
    for s in steps:
        by_kind[s.word] = by_kind.get(s.word, 0.0) + s.duration
    points = {s.point for s in steps if s.point is not None}
    blocks = sum(s.word == "acquire" for s in steps)
    return PlanSummary(len(points), blocks, sum(by_kind.values()), by_kind)
