"""The A/D averaging rule of an Acquire step: how many revolutions a block averages, and which;
and how long an attempt at a block waits."""

from __future__ import annotations

from typing import Callable

from daq.averaging_rule import AveragingRule
from orbitrig.config import Averaging
from orbitrig.run.steps import Acquire
from reduction.rig_time import block_time
from reduction.runout_slip import commanded_speeds, commanded_turns

#: wall s an attempt's waits allow beyond the rig's time (a loaded host)
WALL_SLACK_S = 2.0


def acquire_waits(av: Averaging, orbit: float, revolutions: int, wall: Callable[[float], float]) -> tuple[float, float]:
    """Wall s an attempt at a block of `revolutions` at `orbit` (rad/s) waits (`wall`: physical s
    -> wall s): for the block, `timeout_factor` block times + `timeout_margin_s`; for an A/D
    board that sends nothing, `timeout_margin_s` + two revolutions (a frame spans less than
    one); each + WALL_SLACK_S."""
    timeout = wall(av.timeout_factor * block_time(orbit, revolutions) + av.timeout_margin_s) + WALL_SLACK_S
    return timeout, wall(av.timeout_margin_s + block_time(orbit, 1)) + WALL_SLACK_S


def roll_rule(
    revolutions: int, spin: float, orbit: float, speed_tolerance: float, written: tuple[float, float] | None = None
) -> AveragingRule:
    """The daq rule of a calibration step's slow roll (or reference run) at ``spin`` and ``orbit``
    (rad/s): exactly ``revolutions``, at the speeds the drives were told as a sweep's block
    (:func:`averaging_rule`): its spin turns and the |Omega| its off-speed revolutions
    (``speed_tolerance``, a fraction) are judged against, of ``written`` when given."""
    told = commanded_speeds(spin, orbit, written)
    return AveragingRule(revolutions, revolutions, None, commanded_turns(*told), abs(told[1]), speed_tolerance)


def averaging_rule(
    step: Acquire,
    spin: float,
    speed_tolerance: float = 0.005,
    probes: tuple[int, ...] = (),
    written: tuple[float, float] | None = None,
) -> AveragingRule:
    """The daq rule of an Acquire step at spin (rad/s): its block's adaptive target (percent ->
    a fraction, between min and max revolutions), else exactly its `revolutions`; at the speeds
    the drives were told (reduction.runout_slip.commanded_speeds: as ``written`` to them, rad/s
    spin and orbit, when given, else ``spin`` and the planned orbit; a written speed not finite is
    a ValueError naming the drive): the commanded spin_turns = omega/|Omega| and the ``probes``
    (their channel indices, whose samples fit the block's own ratio, used once resolved: the one
    the sweep's analysis places the runout with), so the check and the block's uncertainty leave
    the spin tones' leakage out; revolutions turned more than ``speed_tolerance`` (fraction) off
    that |Omega| are left out (converted before the orbit drive got there)."""
    told = commanded_speeds(spin, step.block.orbit, written)
    a, orbit, turns = step.adaptive, abs(told[1]), commanded_turns(*told)
    if a is None:
        return AveragingRule(step.revolutions, step.revolutions, None, turns, orbit, speed_tolerance, probes)
    return AveragingRule.adaptive(
        a.target_pct / 100.0,
        a.min_revolutions,
        a.max_revolutions,
        spin_turns=turns,
        orbit_speed=orbit,
        speed_tolerance=speed_tolerance,
        probes=probes,
    )
