"""The A/D averaging rule of an Acquire step: how many revolutions a block averages, and which."""

from __future__ import annotations

from daq.averager import AveragingRule
from orbitrig.run.steps import Acquire


def averaging_rule(step: Acquire, spin: float, speed_tolerance: float = 0.005) -> AveragingRule:
    """The daq rule of an Acquire step at spin (rad/s): its block's adaptive target (percent ->
    a fraction, between min and max revolutions), else exactly its `revolutions`; with
    spin_turns = omega/|Omega|, so the check and the block's uncertainty leave the spin tones'
    leakage out; revolutions turned more than ``speed_tolerance`` (fraction) off the block's
    |Omega| are left out (converted before the orbit drive got there)."""
    a, orbit = step.adaptive, abs(step.block.orbit)
    turns = spin / orbit
    if a is None:
        return AveragingRule(step.revolutions, step.revolutions, None, turns, orbit, speed_tolerance)
    return AveragingRule.adaptive(
        a.target_pct / 100.0,
        a.min_revolutions,
        a.max_revolutions,
        spin_turns=turns,
        orbit_speed=orbit,
        speed_tolerance=speed_tolerance,
    )
