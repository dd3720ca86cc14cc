"""When an averaged block is complete (AveragingRule: fixed, or adaptive to an uncertainty target;
which revolutions are left out for their orbit speed; the spin turns its uncertainty is judged at)
and why it stopped (StopReason). The averaging itself: daq.averager. Pure.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

import numpy as np


class StopReason(StrEnum):
    """Why a block stopped averaging; the value is the word stored with the block and printed."""

    COUNT = "count"  # a fixed rule reached its number of revolutions
    TARGET = "target"  # every channel's relative uncertainty reached the target
    MAX = "max"  # the target was not reached within the maximum


@dataclass(frozen=True)
class AveragingRule:
    """When a block is complete: between ``min_revolutions`` and ``max_revolutions``
    good revolutions; with a ``target`` (relative standard uncertainty of every
    channel's averaged fundamental, a fraction: 0.005 is 0.5 %) as soon as it is met,
    without one at exactly ``max_revolutions`` (the paper's protocol: ``fixed(50)``).
    With ``orbit_speed`` (the set |Omega|, rad/s) a revolution whose measured orbit speed
    (2 pi / its period on the board clock) is off it by more than ``speed_tolerance`` (a
    fraction) was not turned at the operating point (data converted before the drive got
    there, a drive off its setpoint) and is left out (daq.stats ``off_speed``). With
    ``spin_turns`` and ``probes`` (the probe channels' indices) the block's spin ratio is fitted
    from the probes' samples and used once resolved (daq.averager's module docstring)."""

    min_revolutions: int = 50
    max_revolutions: int = 50
    target: float | None = None
    spin_turns: float | None = None  # omega/|Omega|: the target check leaves the spin tones' leakage out
    orbit_speed: float | None = None  # rad/s, the set |Omega|: revolutions off it are left out
    speed_tolerance: float = 0.005  # fraction of orbit_speed
    probes: tuple[int, ...] = ()  # channels whose samples fit the block's spin ratio (none: the commanded one)

    def __post_init__(self) -> None:
        lo, hi, t = self.min_revolutions, self.max_revolutions, self.target
        if not 1 <= lo <= hi:
            raise ValueError(f"revolutions: need 1 <= min ({lo}) <= max ({hi})")
        if t is not None and not (0 < t < np.inf):
            raise ValueError(f"target must be a positive finite fraction, not {t!r}")
        if t is not None and lo < 2:
            raise ValueError("an uncertainty target needs min_revolutions >= 2 (a scatter needs two)")
        if t is None and lo != hi:
            raise ValueError(f"without a target min and max must be equal (got {lo}, {hi})")
        if self.orbit_speed is not None and not (0 < self.orbit_speed < np.inf and 0 < self.speed_tolerance < 1):
            raise ValueError(
                f"orbit speed {self.orbit_speed!r} rad/s, tolerance {self.speed_tolerance!r}: "
                "need a positive finite speed and a tolerance in (0, 1)"
            )

    def off_speed(self, periods: np.ndarray) -> np.ndarray:
        """(R,) bool: which revolutions of measured ``periods`` (s; NaN: unknown, kept) were
        turned off ``orbit_speed`` by more than ``speed_tolerance``."""
        p = np.asarray(periods, dtype=float)
        if self.orbit_speed is None:
            return np.zeros(p.shape, bool)
        with np.errstate(divide="ignore", invalid="ignore"):
            off: np.ndarray = np.abs(2 * np.pi / (p * self.orbit_speed) - 1) > self.speed_tolerance
        kept: np.ndarray = off & ~np.isnan(p)
        return kept

    @classmethod
    def fixed(cls, n: int) -> AveragingRule:
        return cls(n, n, None)

    @classmethod
    def adaptive(
        cls,
        target: float,
        min_revolutions: int = 10,
        max_revolutions: int = 200,
        spin_turns: float | None = None,
        orbit_speed: float | None = None,
        speed_tolerance: float = 0.005,
        probes: tuple[int, ...] = (),
    ) -> AveragingRule:
        """Stop at ``target``; with ``spin_turns`` (omega/|Omega|, commanded) the uncertainty
        checked is reduction.noise.mean_uncertainty (the spin tones' rotating leakage is not noise
        that averaging must beat as 1/sqrt(n)) at the block's ratio (fitted from the ``probes``'
        samples once resolved), else the plain scatter of the per-revolution phasors."""
        return cls(min_revolutions, max_revolutions, target, spin_turns, orbit_speed, speed_tolerance, probes)
