"""The plan's data of a sequential point: the bounds and the candidate blocks, checked once.

`sequential_rule(matrix, rig, spin)` turns a matrix's [sequential] table
(orbitrig.config.sequential) into the `SequentialRule` the plan carries for a point at spin
omega: the model designed for, the target, the cap, and the finite list of candidate ratios
with the whirl directions the engine may choose from at run time. Explicit candidates pass
the same drive-limit checks as the matrix's own ratios (orbitrig.config.sequential.
candidate_problems, in check_matrix_against_rig: the drives' band and the orbit drive's top
speed at every spin, and at least 0.1 from Omega/omega = 1); the default candidates are the
drives' band itself on the design grid (band_candidates).
SI inside: seconds, rad/s; ratios are |Omega| / omega.
"""

from __future__ import annotations

from dataclasses import dataclass

from orbitrig.config import RPM, MatrixConfig, RigConfig, band_candidates
from reduction.whirl import Directions


@dataclass(frozen=True)
class SequentialRule:
    """One sequential point's bounds: ``model`` (kcd11 ...), ``target`` (a fraction of each
    coefficient's scale; None: ``match_ratios`` at ``match_revolutions`` give the standard
    errors to reach), ``cap_s`` (rig s of the point's blocks), ``candidates`` (ratios,
    ascending), ``directions`` (the matrix's whirl directions, each one block), ``per_block_s`` (settle hold + store),
    ``ramp_rate`` (rad/s per s)."""

    model: str
    target: float | None
    match_ratios: tuple[float, ...]
    match_revolutions: int
    cap_s: float
    candidates: tuple[float, ...]
    directions: tuple[Directions, ...]
    per_block_s: float
    ramp_rate: float

    def describe(self) -> str:
        goal = (
            f"every {self.model} coefficient within {self.target * 100:g} % of its size"
            if self.target is not None
            else f"every {self.model} coefficient as precise as ratios {', '.join(f'{r:g}' for r in self.match_ratios)}"
            f" at {self.match_revolutions} revolutions"
        )
        return (
            f"sequential blocks until {goal}, or {self.cap_s:g} s of blocks; candidate ratios "
            f"{', '.join(f'{r:g}' for r in self.candidates)} ({', '.join(self.directions)})"
        )


def sequential_rule(matrix: MatrixConfig, rig: RigConfig, spin: float) -> SequentialRule | None:
    """The rule of a point at ``spin`` (rad/s) of a checked matrix (None: not sequential)."""
    s = matrix.sequential
    if s is None:
        return None
    hold = rig.settle.hold_s if matrix.settle_hold_s is None else matrix.settle_hold_s
    candidates = tuple(sorted(s.candidates)) if s.candidates is not None else band_candidates(rig, spin / RPM)
    return SequentialRule(
        model=matrix.sequential_model or "",
        target=None if s.target_pct is None else s.target_pct / 100.0,
        match_ratios=tuple(sorted(s.match_ratios or ())),
        match_revolutions=s.match_revolutions,
        cap_s=s.cap_s,
        candidates=candidates,
        directions=tuple(Directions(w) for w in matrix.orbit.directions),
        per_block_s=hold + rig.estimates.store_s,
        ramp_rate=rig.ramp_rate,
    )
